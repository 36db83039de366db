"""Controller nodes: thin adapters between the graph's messages and the pure laws."""
