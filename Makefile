# Two entry points (see README): `make run` (default scenario end to end) and `make test`.
# Both create the virtual environment on first use from the pinned requirements.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST

$(VENV)/.installed: requirements.txt requirements-dev.txt setup.py setup.cfg pyproject.toml package.xml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --no-compile --disable-pip-version-check -r requirements-dev.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e . \
		&& test -x $(VENV)/bin/dynamics
	# compile the numba kernels a run uses (plant, Euler angles) into numba's cache beside their modules,
	# two processes at once, one line each (adcs_sim/app/batch/kernels.py; once, then they load)
	$(PY) -m adcs_sim.app.batch.kernels --run
	touch $@

# the other kernels (fused PD loop, campaign metrics, the law's rows): `make run` compiles them after
# its run, `make install`, `make test` and `make bench` before anything else
$(VENV)/.kernels: $(VENV)/.installed
	@echo 'compiling the other numba kernels, once (fused PD loop, campaign metrics, the law rows):'
	$(PY) -m adcs_sim.app.batch.kernels --not-run
	touch $@

.PHONY: install run test bench docs
install: $(VENV)/.kernels

run: $(VENV)/.installed
	$(VENV)/bin/adcs-run $(SCENARIO) --report
	@$(MAKE) -s --no-print-directory $(VENV)/.kernels

test: $(VENV)/.kernels
	$(PY) -m pytest -q -n 2 --dist loadfile --durations=25 tests

# The user guide (docs/, mkdocs.yml) as a static site in site/; any warning fails the build.
docs: $(VENV)/.installed
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict --site-dir site

# BENCH_FLAGS=--basilisk adds the Basilisk comparisons (bsk installed into a throwaway venv in /tmp).
# Not here (tens of minutes): benchmarks/long_run_memory.py, the real 24 h graph run.
bench: $(VENV)/.kernels
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
