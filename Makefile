# Two entry points: `make demo` and `make test`. Each creates .venv if missing and installs
# the project with everything it needs.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test install bench clean

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

bench: $(STAMP)
	$(BIN)/python bench/solvers.py

clean:
	rm -rf $(VENV) demo-output
