# The two commands of the README: `make demo` and `make test`.
# Both create .venv if missing and install contopt into it: `make demo` what the demo needs
# (contopt with the viz and pardiso extras: docs/install.md), `make test` everything it tests
# (all extras that install here, and the dev tools).
# Python 3.12+ where there is one (the PETSc wheel needs it), see scripts/find-python.sh
PYTHON ?= $(shell bash scripts/find-python.sh)
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.contopt-installed
DEMO_STAMP := $(VENV)/.contopt-demo
# pytest worker processes (pytest-xdist); a test file stays on one worker (its module fixtures are made
# once). Most tests are single-threaded Python and small solves: one worker left a 2-core machine 30 % idle
TEST_JOBS ?= 2
PYTEST := $(PY) -m pytest -q -n $(TEST_JOBS) --dist loadfile

# a venv of an older Python than the one found is made again (the petsc extra needs 3.12+)
define make_venv
	if [ -x $(PY) ] && [ "$$($(PY) -c 'import sys; print(sys.version_info[:2])')" != "$$($(PYTHON) -c 'import sys; print(sys.version_info[:2])')" ]; then rm -rf $(VENV); fi
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
endef

.PHONY: setup demo test test-all bench paper-tables docs clean

setup: $(STAMP)

# the extras that compile against system libraries (ipopt, cholmod) or need Python 3.12+ (petsc)
# one by one: one that does not install leaves the others, and the tests skip what needs it
$(STAMP): pyproject.toml scripts/setup-system.sh scripts/find-python.sh
	bash scripts/setup-system.sh test
	$(make_venv)
	$(PY) -m pip install -q -e ".[viz,pardiso,exodus,cad,dev]"
	$(PY) -m pip install -q -e ".[ipopt]" || echo "warning: cyipopt did not install (it needs Ipopt: coinor-libipopt-dev, pkg-config); --optimizer ipopt is unavailable, MMA remains"
	$(PY) -m pip install -q -e ".[cholmod]" || echo "warning: scikit-sparse (CHOLMOD) did not install; pardiso and scipy remain"
	($(PY) -m pip install -q -e ".[petsc]" && $(PY) -m contopt.solve.linear.petsc_install) \
		|| echo "warning: the PETSc wheel did not install (it needs Python 3.12+); the iterative solver (--solver petsc) is unavailable, the direct ones remain"
	touch $(DEMO_STAMP) $(STAMP)

# only what the demo needs: no developer tools, no browser, no compiler
$(DEMO_STAMP): pyproject.toml scripts/setup-system.sh scripts/find-python.sh
	bash scripts/setup-system.sh demo
	$(make_venv)
	$(PY) -m pip install -q -e ".[viz,pardiso]"
	touch $(DEMO_STAMP)

demo: $(DEMO_STAMP)
	$(VENV)/bin/contopt run die-slab --mesh coarse --design bspline --out results --overwrite

# ruff (lint and format, [tool.ruff]) on everything, mypy on src/contopt ([tool.mypy]), then the tests
test: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy
	$(PYTEST) -m "not slow"

test-all: setup
	$(PYTEST)

bench: setup
	mkdir -p bench-out
	$(PY) benchmarks/fe_core.py --out bench-out/fe_core.json
	$(PY) benchmarks/cantilever_topopt.py --out bench-out/cantilever_topopt.json

# the paper's tables 1-3, 7.3 and the sabot: hours on 2 cores (see docs/results.md for what was run)
paper-tables: setup
	$(PY) benchmarks/paper_tables.py --out bench-out/paper_tables.json --doc docs/results.md

# the documentation site (docs/: guides, gallery of the cases, API reference) into build/docs
# (open build/docs/index.html); warnings are errors, as in tests/test_docs_site.py
docs: setup
	$(PY) -m sphinx -b html -q -W --keep-going docs build/docs

clean:
	rm -rf results bench-out .pytest_cache
