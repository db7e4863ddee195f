# Everything a fresh machine needs, from PyPI only (no ROS apt repository).
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# three pytest workers on the two cores: the ROS and process tests wait on DDS and on child
# processes (README's walk-through used a third of a core for its 32 s), and a third worker
# fills those waits: 361 s against 393 s with two, at one seed ten minutes apart (2026-11-30;
# docs/diagnosis.md, section 11, "The suite's time")
JOBS ?= 3
PYTEST_ARGS ?=

# make demo writes DEMO and marks it as its own; a DEMO without the mark is a user's, never
# replaced. Each run replaces the demo's own previous output (diagnose writes it at once).
DEMO ?= out/demo
DEMO_INPUT ?= bags/
DEMO_MARK := .written-by-make-demo

.PHONY: venv test demo bench clean distclean

venv: $(STAMP)

$(STAMP): requirements.txt setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip==24.3.1
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	touch $(STAMP)

# --maxschedchunk=2: each worker holds at most two tests ahead, so the tests marked `long`
# (run first, test/conftest.py) go to whichever worker is free; without it xdist hands each
# worker a quarter of the suite at once, and one worker got every long test. (On the
# command line, not in setup.cfg: colcon test runs pytest where xdist may be absent.)
# PYTEST_ARGS: more pytest options (benchmarks/bench_suite.py adds --durations=0 and -q)
test: venv
	$(PY) -m pytest -n $(JOBS) --maxschedchunk=2 test $(PYTEST_ARGS)

demo: venv
	@if [ -L $(DEMO) ] || { [ -e $(DEMO) ] && [ ! -f $(DEMO)/$(DEMO_MARK) ]; }; then \
	    echo "error: make demo: $(DEMO) exists and was not written by make demo;" \
	        "move it away or run make demo DEMO=another/folder" >&2; exit 3; fi
	rm -rf $(DEMO)
	$(PY) -m octoroach_model diagnose $(DEMO_INPUT) --out $(DEMO) --seed 1 $(DEMO_ARGS)
	touch $(DEMO)/$(DEMO_MARK)

bench: venv
	$(PY) benchmarks/run_all.py

# the build and the demo's own output; the venv and everything else in out/ (studies and
# diagnoses that took hours) stay; distclean removes the venv too
clean:
	rm -rf build install log
	if [ -f $(DEMO)/$(DEMO_MARK) ] && [ ! -L $(DEMO) ]; then rm -rf $(DEMO); fi

distclean: clean
	rm -rf $(VENV)
