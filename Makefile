# Two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install demo test test-slow lint docs bench compare-peers clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# The whole method on the lamp (4 PCwF): heuristic, iterative selection, placement, report.
demo: $(STAMP)
	MPLBACKEND=Agg $(BIN)/closure-nlp plan models/lamp.model.json --contacts 4 --type pcwf \
		--mu 0.2 --seed 1 --seeds 1 --out out/lamp

# The tests not marked slow, over every core (pytest-xdist); each worker builds its solvers once.
test: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m pytest -q -n auto -m "not slow" --durations=15

# The tests marked slow (each over ~10 s: whole suites, real plans, a Dask cluster); CI runs
# them after `make test`.
test-slow: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m pytest -q -n auto -m slow --durations=15

lint: $(STAMP)
	$(BIN)/ruff check closure_nlp tests examples models benchmarks
	$(BIN)/lint-imports

# The API reference of the public names (closure_nlp.__all__), from their docstrings, in site/.
docs: $(STAMP)
	rm -rf site
	MPLBACKEND=Agg $(BIN)/pdoc -d numpy -o site closure_nlp

# The benchmarks of a few minutes each, as JSON in out/bench/, then their tables
# (docs/benchmarks.md). The long ones run by name, e.g. make bench BENCH="startup plans seeds gap
# units characterize model-size".
BENCH ?= rho rho-hat certify engine batch select plan
bench: $(STAMP)
	mkdir -p out/bench
	for what in $(BENCH); do \
		$(BIN)/python -m benchmarks.bench $$what > out/bench/$$what.json || exit 1; \
	done
	$(BIN)/python -m benchmarks.tables $(BENCH:%=out/bench/%.json)

# The outside implementations compared in examples/compare_solvers.py --peers, each in its own
# environment under .peers/ (never part of `make test`). graspnetAPI's own requirements do not
# install on Python 3.11 (it pins numpy==1.20.3; opencv-python's build wants numpy==1.21.2), so
# it goes in without them, beside what Dex-Net's quality module imports, with numpy < 2 (pyhull
# needs it). The GraspIt!-style epsilon is ours and runs in .venv.
PEERS := .peers
KLAMPT_PACKAGES := klampt==0.10.1.post1 'numpy<2.5'
DEXNET_PACKAGES := 'numpy<2' pyhull==2015.2.1 cvxopt scipy matplotlib ipython trimesh \
	scikit-image scikit-learn autolab_core

$(PEERS)/klampt/.installed:
	$(PYTHON) -m venv $(PEERS)/klampt
	$(PEERS)/klampt/bin/python -m pip install --quiet $(KLAMPT_PACKAGES)
	touch $@

$(PEERS)/dexnet/.installed:
	$(PYTHON) -m venv $(PEERS)/dexnet
	$(PEERS)/dexnet/bin/python -m pip install --quiet $(DEXNET_PACKAGES)
	$(PEERS)/dexnet/bin/python -m pip install --quiet --no-deps graspnetapi==1.2.11
	touch $@

compare-peers: $(STAMP) $(PEERS)/klampt/.installed $(PEERS)/dexnet/.installed
	CLOSURE_NLP_PEERS=$(abspath $(PEERS)) MPLBACKEND=Agg $(BIN)/python examples/compare_solvers.py --peers

clean:
	rm -rf $(VENV) build *.egg-info
