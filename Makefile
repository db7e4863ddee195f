# Everything a fresh machine needs, from PyPI only (no ROS apt repository).
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
JOBS ?= 2

.PHONY: venv test demo bench clean

venv: $(STAMP)

$(STAMP): requirements.txt setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip==24.3.1
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	touch $(STAMP)

test: venv
	$(PY) -m pytest -n $(JOBS) test

demo: venv
	$(PY) -m octoroach_model diagnose bags/ --out out/demo --seed 1

bench: venv
	$(PY) benchmarks/run_all.py

clean:
	rm -rf $(VENV) build install log out
