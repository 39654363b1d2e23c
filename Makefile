# parmpm — the README's quick start is `make run` and `make test`.
#
# Both create ./.venv on first use and install parmpm into it (editable) with the MPICH wheel
# (which brings `mpirun`), the test tools and matplotlib. The install is redone only when
# pyproject.toml is newer than the stamp file .venv/.installed.
#
#   make run                      the default scene (2D hanging bar, cpdi, l_cr = 2dx) on NP=2 ranks
#   make run NP=4 RUN_ARGS='run vibrating_bar --quiet'
#   make test                     the linter (ruff) and the test suite on PYTEST_WORKERS=2 worker
#                                 processes (pytest-xdist; 0: one process); pytest options with
#                                 PYTEST_ARGS='-k cli -x' (-m "not slow": no studies)
#   make lint                     only the linter
#   make figures                  run_scripts/tools/make_figures.py, where it exists (the only target
#                                 that writes docs/figures/)
#   make docs                     the documentation site: installs the docs extra into the venv
#                                 (once) and runs mkdocs build --strict into site/ (open
#                                 site/index.html); a broken link or anchor fails it
#   make clean                    caches and build files only; results (parmpm-out/) are kept
#
# PYTHON picks the interpreter that creates the venv (Python >= 3.11): make test PYTHON=python3.12

PYTHON ?= python3
VENV ?= .venv
NP ?= 2
RUN_ARGS ?=
PYTEST_ARGS ?=
# two pytest workers, by measurement (2-core machine, kernels compiled, 2026-11-28): two took
# 466 s, three 506 s (the mpirun tests' ranks then share the cores with a third worker)
PYTEST_WORKERS ?= 2

BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.installed-docs
EXTRAS := mpich,test,plot
# mkdocs-material and a mkdocs plugin print banners about MkDocs 2.0 on every build
DOCS_ENV := NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true

.PHONY: help venv run test lint figures docs clean

help:
	@echo "make run      run the default scene on $(NP) MPI ranks (creates $(VENV) on first use)"
	@echo "make test     run the linter and the test suite (PYTEST_ARGS='...' passes options to pytest)"
	@echo "make lint     run the linter (ruff check)"
	@echo "make figures  regenerate the figures in docs/figures (run_scripts/tools/make_figures.py)"
	@echo "make docs     build the documentation site into site/ (mkdocs build --strict)"
	@echo "make venv     only create $(VENV) and install parmpm[$(EXTRAS)] into it"
	@echo "make clean    remove caches and build files (keeps results: parmpm-out/, run_scripts/out/; keeps $(VENV))"

$(BIN)/python:
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' || \
	  { echo "parmpm needs Python >= 3.11; try: make $(MAKECMDGOALS) PYTHON=python3.11" >&2; exit 1; }
	@$(PYTHON) -m venv $(VENV) || \
	  { echo "'$(PYTHON) -m venv' failed (on Debian/Ubuntu: apt-get install python3-venv)" >&2; exit 1; }

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -e '.[$(EXTRAS)]'
	@touch $@

venv: $(STAMP)

run: $(STAMP)
	$(BIN)/mpirun -n $(NP) $(BIN)/python -m parmpm $(RUN_ARGS)

test: lint
	$(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

lint: $(STAMP)
	$(BIN)/ruff check .

$(DOCS_STAMP): pyproject.toml $(STAMP)
	$(BIN)/python -m pip install -e '.[$(EXTRAS),docs]'
	@touch $@

docs: $(DOCS_STAMP)
	$(DOCS_ENV) $(BIN)/mkdocs build --strict --site-dir site

figures: $(STAMP)
	@if [ -f run_scripts/tools/make_figures.py ]; then \
	  $(BIN)/python run_scripts/tools/make_figures.py; \
	else \
	  echo "run_scripts/tools/make_figures.py does not exist yet (planned)"; \
	fi

# Results are never cleaned: parmpm-out/ (runs) and run_scripts/out/ (studies) stay. Removing
# __pycache__ also empties numba's cache of the sources here (kernels recompile on the next run);
# a NUMBA_CACHE_DIR elsewhere is yours to empty.
clean:
	rm -rf .pytest_cache build *.egg-info
	find . -path ./$(VENV) -prune -o -path ./parmpm-out -prune -o -path ./run_scripts/out -prune \
	  -o -name __pycache__ -type d -exec rm -rf {} +
