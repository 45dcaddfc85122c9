# Two commands for a fresh machine:  `make run`  and  `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.installed

.PHONY: run test test-slow validate bench calibrate clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

# The main job: simulate the flagship case, write HDF5 + XDMF + a plot against experiment.
run: $(STAMP)
	$(VENV)/bin/fpsi run elastic_gate --out results/elastic_gate.h5 --every 0.01 --plot --overwrite

# The default test suite (long validation runs are marked slow and run in experiments/).
test: $(STAMP)
	$(PY) -m pytest -q -n auto --maxprocesses 4

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow -n auto --maxprocesses 4

validate: $(STAMP)
	$(VENV)/bin/fpsi validate

# The ready-made calibrations (cantilever: ~10 min; elastic gate, coarse: ~30 min).
calibrate: $(STAMP)
	$(PY) experiments/calibrate_cantilever.py
	$(PY) experiments/calibrate_gate.py

bench: $(STAMP)
	$(PY) experiments/bench_sph.py

clean:
	rm -rf $(VENV) results .pytest_cache
