# Two set-up commands (see README): `make demo` and `make test`. Both create the virtual environment.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
DEMO_DB ?= build/sample.mdb

.PHONY: install demo test test-fast bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $@

install: $(VENV)/.installed

demo: install
	$(BIN)/mocapviz ingest "$$($(BIN)/mocapviz datasets fetch sample)" --out $(DEMO_DB)
	$(BIN)/mocapviz info $(DEMO_DB)

test: install
	$(PY) -m pytest tests notebooks --nbmake

test-fast: install
	$(PY) -m pytest tests -m "not slow"

bench: install
	$(PY) -m benchmarks

clean:
	rm -rf build .cache
