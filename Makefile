# lotsen: two commands set everything up.
#   make run   - virtual environment + the on-board dependencies, then the full stack on the simulated boat
#   make test  - virtual environment + test dependencies (and Debian's Chromium for browser tests), then all tests
#   make bench - benchmarks, results in bench/results/ (table .md + .json); BASELINE=../main-worktree
#                pairs the footprint bench with that checkout (idle CPU, page, helm under a flood)
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip --disable-pip-version-check
RUN_ARGS ?=

.PHONY: run test test-under-load bench bench-quick venv venv-dev browser clean pi-check

$(VENV)/.run-installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q -e .
	touch $@

$(VENV)/.dev-installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q -e '.[dev]'
	touch $@ $(VENV)/.run-installed

venv: $(VENV)/.run-installed
venv-dev: $(VENV)/.dev-installed

browser:
	@bash tools/ensure-chromium.sh

run: venv
	$(PY) -m lotsen run config/sim.yaml --sim $(RUN_ARGS)

# Three steps: everything that runs on simulated time (deterministic, two workers); then the `live`
# tests (lotsen run and the emulated devices at wall-clock pace) two at a time, after the first step
# so they do not compete with it for the two cores (a live run mostly waits for its clock: two use
# about a third of one core; each core takes a CPU the other's does not hold); then the `alone` ones
# (timing under a load they make themselves: the viewer flood, a survey's route arriving; an external
# physics that must keep step with the core) on their own. The 25 slowest simulated-time tests are listed (what the suite's time goes to). A live test
# that fails is run once more, on its own.
# (tools/test_under_load.py reads these two selections from here)
LIVE_PAIRED := live and not alone and not timing_bar
LIVE_ALONE := live and alone and not timing_bar
test: venv-dev browser
	$(PY) -m pytest -q -n 2 --dist loadfile -m "not live" --durations=25
	$(PY) -m pytest -q -n 2 --dist loadfile -m "$(LIVE_PAIRED)" || $(PY) -m pytest -q -m "$(LIVE_PAIRED)" --last-failed
	$(PY) -m pytest -q -m "$(LIVE_ALONE)" || $(PY) -m pytest -q -m "$(LIVE_ALONE)" --last-failed

# The default suite 10 times in a row with two CPU burners running (RUNS=, BURNERS=); writes
# bench/results/under_load.md. About 15-19 min a run on a 2-core machine with the burners: 2.5-3 h.
RUNS ?= 10
BURNERS ?= 2
test-under-load: venv-dev browser
	$(PY) tools/test_under_load.py --runs $(RUNS) --burners $(BURNERS)

bench: venv-dev
	$(PY) bench/run.py $(if $(BASELINE),--baseline $(BASELINE))

bench-quick: venv-dev
	$(PY) bench/run.py --quick

# arm64 Debian bookworm (the Raspberry Pi OS base) under qemu: install as the README says, then
# `lotsen check --emulated`, a short `lotsen run --sim` and the unit tests without a browser.
# Root, network, ~20 min the first time (the root file system is cached); not part of `make test`.
pi-check:
	bash tools/pi-check.sh

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info
