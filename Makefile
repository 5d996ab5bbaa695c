# Two entry points: `make demo` and `make test`. Each creates .venv if missing and installs
# the project with everything it needs.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-mpi install bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/pip install -q -e ".[full,fast,test,ansys,exudyn]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/flexmor demo --out demo-output

test: $(STAMP)
	$(BIN)/python -m pytest

# The petsc backend under MPI: a second environment on the system Python, which sees Debian's
# petsc4py/slepc4py/mpi4py (apt-get install python3-petsc4py python3-slepc4py python3-mpi4py
# openmpi-bin); numpy < 2 because those modules are built against Debian's numpy 1.x.
SYSTEM_PYTHON ?= /usr/bin/python3
VENV_MPI := .venv-mpi
MPI_STAMP := $(VENV_MPI)/.installed

$(MPI_STAMP): pyproject.toml
	$(SYSTEM_PYTHON) -m venv --system-site-packages $(VENV_MPI)
	$(VENV_MPI)/bin/pip install -q "numpy>=1.26,<2" -e ".[full,test]"
	@# Debian's petsc4py/slepc4py .pth files need PETSC_DIR/SLEPC_DIR unless the -dev packages are installed
	ls -d /usr/lib/petscdir/petsc*/*-real/lib/python3/dist-packages /usr/lib/slepcdir/slepc*/*-real/lib/python3/dist-packages \
		> "$$($(VENV_MPI)/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/debian-petsc-real.pth" \
		2>/dev/null || true
	touch $(MPI_STAMP)

test-mpi: $(MPI_STAMP)
	$(VENV_MPI)/bin/python -m pytest -q tests/test_petsc.py

bench: $(STAMP)
	$(BIN)/python bench/solvers.py

clean:
	rm -rf $(VENV) $(VENV_MPI) demo-output
