# Two set-up commands (see README): `make demo` and `make test`. Both create the virtual environment.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
# what `make demo` serves: the embedded demo (default), `ARCHIVES=all` for every shared archive of ../shared/data
# (446k frames at 30 Hz; the first run ingests for minutes), or a list of archive names (`mocapviz datasets list`)
ARCHIVES ?= demo
ALL_ARCHIVES := hdm05-cut cmu-asfamc bandai-namco-1 bandai-namco-2 c3d-markers
DEMO_ARCHIVES := $(if $(filter all,$(ARCHIVES)),$(ALL_ARCHIVES),$(ARCHIVES))
empty :=
space := $(empty) $(empty)
DEMO_DB ?= build/$(subst $(space),+,$(strip $(ARCHIVES))).mdb
PORT ?= 5006
LAB_PORT ?= 8888
CHROMIUM := /usr/bin/chromium
# Debian's Chromium for the dashboard's browser tests (never `playwright install`) and Mesa's EGL / OSMesa for
# PyVista's offscreen rendering; installed once, as root or through sudo
SYSTEM_PACKAGES := chromium libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6
# the Khronos glTF validator (npm) for the glTF export's test (tests/test_export.py), under .cache (not in git)
GLTF_VALIDATOR := .cache/gltf/node_modules/gltf-validator
# the clients that open exported files in tests/test_clients.py, under .cache (not in git): Blender as the bpy wheel
# (CPython 3.11 only; its own venv, so that its numpy pin stays out of .venv) and three.js (npm)
BPY_VERSION := 5.0.1
BLENDER_VENV := .cache/blender
BLENDER_PY := $(BLENDER_VENV)/bin/python
THREE_VERSION := 0.187.0
THREEJS := .cache/threejs/node_modules/three

.PHONY: install demo lab docs test test-fast gltf-validator blender threejs notebooks-full reproduce bench clean

# the checkout on sys.path through a .pth file (setuptools' compat editable mode), not an import hook: a script run
# from the folder above a checkout named mocapviz/ would otherwise import that folder as an empty namespace package
EDITABLE := --config-settings editable_mode=compat

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,bench]' $(EDITABLE)
	touch $@

install: $(VENV)/.installed

# JupyterLab and ipywidgets (the `notebook` extra) beside the test install
$(VENV)/.notebook: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test,bench,notebook]' $(EDITABLE)
	touch $@

# Sphinx, its theme and extensions (the `docs` extra) beside the test install
$(VENV)/.docs: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test,bench,docs]' $(EDITABLE)
	touch $@

$(CHROMIUM):
	@if [ "$$(id -u)" = 0 ]; then SUDO=; elif command -v sudo >/dev/null; then SUDO=sudo; else \
	  echo "the browser tests need Debian's packages: apt-get install $(SYSTEM_PACKAGES)" >&2; exit 1; fi; \
	  $$SUDO apt-get update -qq && $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(SYSTEM_PACKAGES)

$(GLTF_VALIDATOR):
	@if command -v npm >/dev/null; then npm install --silent --prefix .cache/gltf gltf-validator; else \
	  echo "the glTF validator needs node and npm (apt-get install nodejs npm); its test skips without them" >&2; fi

gltf-validator: $(GLTF_VALIDATOR)

# a half-made venv is removed, so that the tests see Blender installed or not at all
$(BLENDER_PY):
	@rm -rf $(BLENDER_VENV); if ! { $(PYTHON) -m venv $(BLENDER_VENV) && \
	  $(BLENDER_VENV)/bin/pip install --quiet bpy==$(BPY_VERSION); }; then rm -rf $(BLENDER_VENV); \
	  echo "bpy $(BPY_VERSION) did not install (it needs CPython 3.11 as $(PYTHON)); tests/test_clients.py skips (under make test: fails) its Blender tests without it" >&2; fi

blender: $(BLENDER_PY)

$(THREEJS):
	@if command -v npm >/dev/null; then npm install --silent --prefix .cache/threejs three@$(THREE_VERSION); else \
	  echo "three.js needs node and npm (apt-get install nodejs npm); tests/test_clients.py skips (under make test: fails) its three.js tests without it" >&2; fi

threejs: $(THREEJS)

# the embedded demo (or ARCHIVES) as a MotionDB at 30 Hz with its relational indexes and numeric feature sets, then
# the dashboard on http://127.0.0.1:$(PORT)/ (Ctrl-C stops it). The demo's folders go in in DEMO_ORDER (HDM05
# first); a file that cannot be read is skipped with a warning naming it. Ingesting again adds nothing new.
demo: install
	folders=$$(for name in $(DEMO_ARCHIVES); do folder=$$($(BIN)/mocapviz datasets fetch $$name) || exit 1; \
	  if [ $$name = demo ]; then echo $$folder/hdm05-cut $$folder/cmu-asfamc $$folder/c3d-markers; \
	  else echo $$folder; fi; done) && \
	  $(BIN)/mocapviz ingest $$folders --out $(DEMO_DB) --fps 30 --skip-bad --no-cluster
	$(BIN)/mocapviz index $(DEMO_DB) --no-cluster --quiet
	$(BIN)/mocapviz features $(DEMO_DB) --no-cluster --quiet
	$(BIN)/mocapviz serve $(DEMO_DB) --port $(PORT)

# JupyterLab on the notebooks folder, without opening a browser: open the http://127.0.0.1:$(LAB_PORT)/lab?token=...
# address it prints (Ctrl-C stops it); notebooks/12_search_your_database.ipynb starts from your own folder
lab: $(VENV)/.notebook
	$(BIN)/jupyter lab --no-browser --ip=127.0.0.1 --port=$(LAB_PORT) --ServerApp.root_dir=notebooks \
	  $$([ "$$(id -u)" = 0 ] && echo --allow-root)

# the documentation site (docs/conf.py) into build/docs/html (open build/docs/html/index.html): the guide's pages,
# the API reference from the docstrings, the CLI reference from the parser, the notebooks executed (cached in
# build/docs/jupyter_cache: a notebook runs again only when its code changes); any warning, an unresolved link or
# reference included, fails it. The first build takes 7.5 min on 2 cores (7.3 of them the notebooks), later ones
# seconds. `make test` builds it too (tests/test_docs_site.py), so it installs the docs extra
docs: $(VENV)/.docs
	$(PY) -m sphinx -q -c docs -W --keep-going . build/docs/html

# every test, the docstrings' Examples as doctests; the notebooks are executed once, by the documentation site's
# build in tests/test_docs_site.py (a cell's error fails it, naming the notebook), not a second time by nbmake
test: $(VENV)/.docs $(CHROMIUM) $(GLTF_VALIDATOR) $(BLENDER_PY) $(THREEJS)
	MOCAPVIZ_REQUIRE_BROWSER=1 $(PY) -m pytest --doctest-modules --durations=40 mocapviz tests

test-fast: install
	$(PY) -m pytest --doctest-modules mocapviz tests -m "not slow"

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
