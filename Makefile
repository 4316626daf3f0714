# The two commands of the README: `make demo` and `make test`.
# Both create .venv if missing and install contopt with its dependencies.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.contopt-installed

.PHONY: setup demo test test-all bench paper-tables docs clean

setup: $(STAMP)

$(STAMP): pyproject.toml scripts/setup-system.sh
	bash scripts/setup-system.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[dev]"
	$(PY) -m pip install -q -e ".[cholmod]" || echo "warning: scikit-sparse (CHOLMOD) did not install; pardiso and scipy remain"
	touch $(STAMP)

demo: setup
	$(VENV)/bin/contopt run die-slab --mesh coarse --design bspline --out results --overwrite

# ruff (lint and format, [tool.ruff]) on everything, mypy on the typed core ([tool.mypy]), then the tests
test: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy
	$(PY) -m pytest -q -m "not slow"

test-all: setup
	$(PY) -m pytest -q

bench: setup
	mkdir -p bench-out
	$(PY) benchmarks/fe_core.py --out bench-out/fe_core.json
	$(PY) benchmarks/cantilever_topopt.py --out bench-out/cantilever_topopt.json

# the paper's tables 1-3, 7.3 and the sabot: hours on 2 cores (see docs/results.md for what was run)
paper-tables: setup
	$(PY) benchmarks/paper_tables.py --out bench-out/paper_tables.json --doc docs/results.md

# the API reference from the docstrings, into build/api (open build/api/index.html)
docs: setup
	$(PY) -m sphinx -b html -q docs/api build/api

clean:
	rm -rf results bench-out .pytest_cache
