# Every target sets up .venv itself (pinned by requirements.lock) before it runs.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export PYTHONDONTWRITEBYTECODE :=

.PHONY: venv test demo bench proof proof-extend lint clean

venv: $(STAMP)

$(STAMP): requirements.lock setup.py setup.cfg package.xml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -r requirements.lock
	$(PY) -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e .
	@echo "compiling the Magic Formula kernels into the numba cache (once per install)"
	$(PY) -c "from tire_model_ros.model.kernel import warm_up; warm_up()"
	touch $(STAMP)

test: venv
	$(VENV)/bin/ruff check tire_model_ros test bench realities
	$(VENV)/bin/ruff format --check tire_model_ros test bench realities
	$(VENV)/bin/mypy
	$(PY) -m pytest -q -n 2 --dist loadfile test  # two workers, a test file on one of them

demo: venv
	$(PY) -m tire_model_ros.demo

bench: venv
	$(PY) bench/bench_model.py
	$(PY) bench/bench_node.py
	$(PY) bench/bench_recording.py
	$(PY) bench/bench_fit.py
	$(PY) bench/bench_import.py

proof: venv
	$(PY) bench/proof.py --jobs 2

proof-extend: venv
	$(PY) bench/proof_extend.py

lint: venv
	$(VENV)/bin/ruff check tire_model_ros test bench realities
	$(VENV)/bin/ruff format --check tire_model_ros test bench realities
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) build install log .pytest_cache
