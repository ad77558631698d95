# frbench: one command sets up and runs the main job (`make demo`), one sets up and
# runs the tests (`make test`). Both create and reuse a local virtual environment
# (.venv) with the pinned versions of requirements.lock; torch is pinned to the
# CPU build 2.13.0. The lock includes the optional extras' packages (cma, Ray), so their tests run.

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.frbench-installed

.PHONY: install demo test test-slow test-browser bench clean

$(STAMP): pyproject.toml requirements.lock
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -r requirements.lock
	$(BIN)/pip install --quiet --no-deps -e .
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/frbench robots
	$(BIN)/frbench robot check go2
	$(BIN)/frbench evaluate

test: $(STAMP)
	$(BIN)/python -m pytest
	$(BIN)/frbench leaderboard --check

test-slow: $(STAMP)
	$(BIN)/python -m pytest -m slow

test-browser: $(STAMP)
	command -v chromium >/dev/null || (apt-get update -qq && apt-get install -y -qq chromium)
	$(BIN)/python -m pytest -m browser tests/test_leaderboard_browser.py

bench: $(STAMP)
	$(BIN)/python benchmarks/throughput.py
	$(BIN)/python benchmarks/evaluation_throughput.py
	$(BIN)/python benchmarks/terrain_throughput.py
	$(BIN)/python benchmarks/training_throughput.py
	$(BIN)/python benchmarks/split_training_throughput.py

clean:
	rm -rf $(VENV)
