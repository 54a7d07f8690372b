# Two set-up commands: `make demo` and `make test`. Both create .venv and install into it.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-quick notebooks bench docs clean atlas

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	mkdir -p demo
	$(VENV)/bin/cosserat-channel run sweeps/quickstart.toml
	$(VENV)/bin/cosserat-channel info demo/quickstart.nc
	$(VENV)/bin/cosserat-channel plot demo/quickstart.nc --x eps --y Delta --hue L --at K=0.5,A=0.3333333333333333,N=1 -o demo/delta_vs_eps.png
	$(VENV)/bin/cosserat-channel point --eps 0.0333333333333 --L 10 --K 0.5 --A 0.3333333333333 --N 1 --plot demo/point_fig2.png
	@echo "demo outputs are in demo/"

# The tests run in TEST_WORKERS processes (pytest-xdist; CI's machine has 2 cores), the slow ones
# first (tests/conftest.py).
# TEST_WORKERS=0 runs them in this process alone.
TEST_WORKERS ?= 2
PYTEST := $(PY) -m pytest -q -n $(TEST_WORKERS)

test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks
	$(PYTEST) --durations=20

# Daily work: everything but the tests marked slow (`make test` and CI run them all).
test-quick: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks
	$(PYTEST) -m "not slow"

# Installs JupyterLab into .venv (the `notebooks` extra) and opens notebooks/ in the browser.
# Jupyter refuses to start as root without --allow-root (a container, a CI machine).
notebooks: $(STAMP)
	$(PY) -m pip install --quiet -e '.[notebooks]'
	$(VENV)/bin/jupyter lab notebooks/$(if $(filter 0,$(shell id -u)), --allow-root)

bench: $(STAMP)
	$(PY) benchmarks/bench_point.py

# The whole-plane solvability atlas that the package carries (package data): the default
# arguments of `atlas` over the whole plane. A rebuild with the same sources writes the same file.
atlas: $(STAMP)
	$(VENV)/bin/cosserat-channel atlas --A=-1:5 --N=0.3:3 --tol 1e-8 \
	    -o src/cosserat_channel/atlas/data/whole_plane.nc --overwrite
	$(VENV)/bin/python -c "from cosserat_channel.atlas.store import record_shipped_digest as r; print(r())"

# The documentation site, into docs/_build/html (the `test` extra includes the `docs` extra):
# executes the notebooks into docs/_generated/notebooks (small mode; the repository keeps them
# without outputs), draws the paper's figures into docs/_generated/paper, then builds with
# warnings as errors. The first two steps run again only when the package's sources (or the
# notebook) change; Sphinx reads every page each time (-E): an incremental build skips the pages
# that warned before, and would pass where a fresh clone fails.
SOURCES    := $(shell find src -name '*.py')
NOTEBOOKS  := $(wildcard notebooks/*.ipynb)
EXECUTED   := $(patsubst notebooks/%,docs/_generated/notebooks/%,$(NOTEBOOKS))

docs/_generated/notebooks/%.ipynb: notebooks/%.ipynb $(SOURCES) $(STAMP)
	$(PY) docs/run_notebook.py $< docs/_generated/notebooks

docs/_generated/paper/comparison.md: $(SOURCES) $(STAMP)
	$(VENV)/bin/cosserat-channel paper -o docs/_generated/paper --overwrite

docs: $(EXECUTED) docs/_generated/paper/comparison.md
	$(VENV)/bin/sphinx-build -W --keep-going -E -q -b html docs docs/_build/html
	@echo "documentation: docs/_build/html/index.html"

clean:
	rm -rf $(VENV) demo docs/_build docs/_generated
