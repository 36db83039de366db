"""Analysis of a run: metrics (in memory, streamed, batched), run data from bags, adcs-analyze and adcs-bag-repair."""
