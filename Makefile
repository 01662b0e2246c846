# buildenv — `make demo` and `make test` work on a fresh machine (Python >= 3.10 with venv).
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install demo test test-all bench dataset clean

$(STAMP): pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# torch pinned first so that nothing pulls a CUDA build
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

demo: install
	$(VENV)/bin/buildenv demo --out out/demo

test: install
	$(PY) -m pytest -m "not slow" -q

test-all: install
	$(PY) -m pytest -q

bench: install
	$(PY) bench/simulation_speed.py

# The training dataset of the metamodel issue (about 5 minutes on 2 cores).
dataset: install
	$(VENV)/bin/buildenv simulate --weeks 5200 --seed 0 --out data/campaign-5200

clean:
	rm -rf out .pytest_cache
