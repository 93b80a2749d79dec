# tensegrity_ros: `make run` and `make test` set up .venv from the pinned
# requirements on first use, then run. DDS stays on loopback everywhere.
SHELL := /bin/bash
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
CONFIG ?= config/default.yaml
PYTEST_ARGS ?=

export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
# One DDS domain per make invocation unless the caller chose one.
ROS_DOMAIN_ID ?= $(shell $(PYTHON) -c 'import os; print(1 + os.getpid() % 100)')
export ROS_DOMAIN_ID
export PYTHONUNBUFFERED := 1

.PHONY: setup run test bench figures clean

setup: $(STAMP)

$(STAMP): requirements.txt setup.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	touch $(STAMP)

run: $(STAMP)
	@echo "tensegrity_node on $(CONFIG), ROS_DOMAIN_ID=$(ROS_DOMAIN_ID), discovery LOCALHOST"
	$(PY) -m tensegrity_ros.node --ros-args --params-file $(CONFIG)

test: $(STAMP)
	ROS_PYTHON_CHECK_FIELDS=1 $(PY) -m pytest $(PYTEST_ARGS)

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .hypothesis
