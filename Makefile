# Two entry points: `make demo` and `make test`. Each creates .venv if missing and installs
# the project with everything it needs, at the exact versions of the lock constraints.txt
# (every package, transitive ones and the build backend included; `make lock` refreshes it).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
EXTRAS := full,fast,test,ansys,exudyn,mesh,amg
MPI_EXTRAS := full,test

.PHONY: demo lint test test-arith test-wheel test-mpi install bench clean lock docs

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# PIP_CONSTRAINT also reaches pip's isolated build environment (setuptools, wheel)
$(STAMP): $(BIN)/python pyproject.toml constraints.txt
	PIP_CONSTRAINT=constraints.txt $(BIN)/pip install -q -c constraints.txt -e ".[$(EXTRAS)]"
	touch $(STAMP)

# Refresh the locks from the pyproject.toml ranges: newest versions that install on this Python,
# resolved in throw-away environments. Commit constraints*.txt after `make test` passes with them.
lock:
	rm -rf .venv-lock && $(PYTHON) -m venv .venv-lock
	.venv-lock/bin/pip install -q --upgrade setuptools wheel
	.venv-lock/bin/pip install -q -e ".[$(EXTRAS),docs]"
	{ echo "# make lock: exact versions for make demo / make test ($$(.venv-lock/bin/python -V))"; \
	  .venv-lock/bin/pip freeze --all --exclude-editable | grep -v -E '^pip=='; } > constraints.txt.tmp
	mv constraints.txt.tmp constraints.txt
	rm -rf .venv-lock && $(PYTHON) -m venv .venv-lock
	.venv-lock/bin/pip install -q --upgrade setuptools wheel
	.venv-lock/bin/pip install -q "numpy>=1.26,<2" -e ".[$(MPI_EXTRAS)]"
	{ echo "# make lock: exact versions for make test-mpi (numpy 1.x for Debian's petsc4py)"; \
	  .venv-lock/bin/pip freeze --all --exclude-editable | grep -v -E '^pip=='; } > constraints-mpi.txt.tmp
	mv constraints-mpi.txt.tmp constraints-mpi.txt
	rm -rf .venv-lock

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/flexmor demo --out demo-output

# ruff on src/ and tests/, mypy on the modules listed as files in [tool.mypy] of pyproject.toml
lint: $(STAMP)
	$(BIN)/ruff check src tests
	$(BIN)/mypy

test: lint
	$(BIN)/python -m pytest

# The tests once more on another arithmetic path, so that a test that passes only with one rounding fails
# here: SciPy's SuperLU wherever `auto` would take PARDISO or CHOLMOD (FLEXMOR_AUTO_BACKENDS), OpenBLAS's
# Haswell kernels instead of the ones it picks for this CPU, and one BLAS thread. The browser tests, the
# fuzzers and the resource-limit runs (no numerics) are left out.
ARITH_ENV := FLEXMOR_AUTO_BACKENDS=scipy OPENBLAS_CORETYPE=Haswell OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
test-arith: $(STAMP)
	$(ARITH_ENV) $(BIN)/python -m pytest -m "not browser and not mpi" \
		--ignore=tests/test_ui_fuzz.py --ignore=tests/test_fuzz_readers.py --ignore=tests/test_bad_corpus.py \
		--ignore=tests/test_resource_faults.py

# The package a user installs: sdist and wheel built (python -m build: the wheel from the sdist), the wheel
# installed with the lock in a clean environment, and the tests that use its entry points and each of its
# package-data files (the FMU's C runtime, the 3D viewer's JavaScript, the web app's page) run against it.
VENV_WHEEL := .venv-wheel
WHEEL_TESTS := tests/test_installed.py tests/test_cli.py tests/test_export_fmu.py tests/test_view3d.py tests/test_ui.py
test-wheel: $(STAMP)
	rm -rf dist $(VENV_WHEEL)
	PIP_CONSTRAINT=constraints.txt $(BIN)/python -m build --outdir dist . >/dev/null
	$(PYTHON) -m venv $(VENV_WHEEL)
	PIP_CONSTRAINT=constraints.txt $(VENV_WHEEL)/bin/pip install -q -c constraints.txt \
		"$$(ls dist/flexmor-*.whl)[$(EXTRAS)]"
	FLEXMOR_TEST_INSTALLED=1 $(VENV_WHEEL)/bin/python -m pytest -p no:cacheprovider $(WHEEL_TESTS)

# The petsc backend under MPI: a second environment on the system Python, which sees Debian's
# petsc4py/slepc4py/mpi4py (apt-get install python3-petsc4py python3-slepc4py python3-mpi4py
# openmpi-bin); numpy < 2 because those modules are built against Debian's numpy 1.x.
SYSTEM_PYTHON ?= /usr/bin/python3
VENV_MPI := .venv-mpi
MPI_STAMP := $(VENV_MPI)/.installed

$(MPI_STAMP): pyproject.toml constraints-mpi.txt
	$(SYSTEM_PYTHON) -m venv --system-site-packages $(VENV_MPI)
	PIP_CONSTRAINT=constraints-mpi.txt $(VENV_MPI)/bin/pip install -q -c constraints-mpi.txt "numpy>=1.26,<2" -e ".[$(MPI_EXTRAS)]"
	@# Debian's petsc4py/slepc4py .pth files need PETSC_DIR/SLEPC_DIR unless the -dev packages are installed
	ls -d /usr/lib/petscdir/petsc*/*-real/lib/python3/dist-packages /usr/lib/slepcdir/slepc*/*-real/lib/python3/dist-packages \
		> "$$($(VENV_MPI)/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/debian-petsc-real.pth" \
		2>/dev/null || true
	touch $(MPI_STAMP)

test-mpi: $(MPI_STAMP)
	$(VENV_MPI)/bin/python -m pytest tests/test_petsc.py

# The documentation site: Sphinx (numpydoc, MyST Markdown, pydata theme) with the docs extra at the lock's
# versions; warnings are errors (a broken reference, a public name without docstring), the gallery runs
# the examples at a small size. Output in docs/_build/html (open docs/_build/html/index.html).
DOCS_STAMP := $(VENV)/.installed-docs
$(DOCS_STAMP): $(STAMP)
	PIP_CONSTRAINT=constraints.txt $(BIN)/pip install -q -c constraints.txt -e ".[$(EXTRAS),docs]"
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	rm -rf docs/_build docs/generated docs/auto_examples
	MPLBACKEND=Agg $(BIN)/sphinx-build -W --keep-going -q -b html docs docs/_build/html

bench: $(STAMP)
	$(BIN)/python bench/solvers.py

# docs/benchmark.md: every reduction method on the benchmark's models; writes the page's tables
.PHONY: benchmark
benchmark: $(STAMP)
	$(BIN)/python bench/benchmark.py

clean:
	rm -rf $(VENV) $(VENV_MPI) $(VENV_WHEEL) dist .venv-lock demo-output docs/_build docs/generated docs/auto_examples
