# Two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install demo test test-fast lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# The whole method on the lamp (4 PCwF): heuristic, iterative selection, placement, report.
demo: $(STAMP)
	MPLBACKEND=Agg $(BIN)/closure-nlp plan models/lamp.model.json --contacts 4 --type pcwf \
		--mu 0.2 --seed 1 --out out/lamp

test: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m pytest -q

test-fast: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m pytest -q -m "not slow"

lint: $(STAMP)
	$(BIN)/ruff check closure_nlp tests examples models

bench: $(STAMP)
	$(BIN)/python -m closure_nlp.bench rho
	$(BIN)/python -m closure_nlp.bench rho-hat
	$(BIN)/python -m closure_nlp.bench certify
	$(BIN)/python -m closure_nlp.bench select
	$(BIN)/python -m closure_nlp.bench plan

clean:
	rm -rf $(VENV) build *.egg-info
