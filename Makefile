# Two set-up commands (see README): `make demo` and `make test`. Both create the virtual environment.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
DEMO_DB ?= build/sample.mdb

.PHONY: install demo test test-fast notebooks-full reproduce bench clean

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

# the notebooks at the papers' sizes (MOCAPVIZ_FULL=1: more random queries, the largest shared database); slow
notebooks-full: install
	MOCAPVIZ_FULL=1 $(PY) -m pytest notebooks --nbmake --nbmake-timeout=7200

# every experiment's tables and figures (CSV, PNG, HTML) into build/reproduce; FULL=1 for the papers' sizes
reproduce: install
	$(BIN)/mocapviz reproduce all --out build/reproduce $(if $(FULL),--full,)

# every benchmark (long: builds 1M- and 4M-frame databases once, cached in .cache/bench): markdown tables,
# benchmarks/results/*.csv and one report, benchmarks/REPORT.md
bench: install
	$(PY) -m benchmarks

clean:
	rm -rf build .cache
