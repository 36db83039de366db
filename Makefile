# Two entry points (see README): `make run` (default scenario end to end) and `make test`.
# Both create the virtual environment on first use from the pinned requirements.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST

$(VENV)/.installed: requirements.txt requirements-dev.txt setup.py setup.cfg pyproject.toml package.xml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-dev.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps -e . && test -x $(VENV)/bin/dynamics
	$(PY) -c 'import numpy; from adcs_sim.truth.plant import Plant; Plant(numpy.eye(3))'  # compile the plant kernel into its cache
	# compile the campaigns' fused PD loop and batch-metrics kernels (~60 s once; cached beside their modules)
	$(PY) -c 'from adcs_sim.app.campaign import Campaign, run_chunk; c = Campaign.load("config/campaigns/pd_slew_30deg.yaml", runs=2); [r for ch in c.chunks() for r in run_chunk(c, ch)]'
	$(PY) -c 'from adcs_sim.app.metrics_kernel import compile_rare_kernels; compile_rare_kernels()'
	touch $@

.PHONY: install run test bench
install: $(VENV)/.installed

run: $(VENV)/.installed
	$(VENV)/bin/adcs-run $(SCENARIO) --report

test: $(VENV)/.installed
	$(PY) -m pytest -q -n 2 --dist loadfile --durations=25 tests

# BENCH_FLAGS=--basilisk adds the Basilisk comparisons (bsk installed into a throwaway venv in /tmp).
# Not here (tens of minutes): benchmarks/long_run_memory.py, the real 24 h graph run.
bench: $(VENV)/.installed
	$(PY) benchmarks/plant_step.py $(BENCH_FLAGS)
	$(PY) benchmarks/montecarlo_speed.py $(BENCH_FLAGS)
	$(PY) benchmarks/showcase_graph.py --pd
	$(PY) benchmarks/lockstep_vs_pingpong.py
	$(PY) benchmarks/analysis_speed.py --memory
	$(PY) benchmarks/recorder_executor.py
	$(PY) benchmarks/batch_vs_loop.py
	$(PY) benchmarks/pointing_montecarlo.py
	$(PY) benchmarks/law_step.py
	$(PY) benchmarks/cdr_codec.py
	$(PY) benchmarks/startup_timeline.py
	$(PY) benchmarks/report_speed.py --hours 0
	$(PY) benchmarks/recorder_memory.py --writer
