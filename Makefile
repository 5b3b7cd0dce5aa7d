# Two set-up commands on a fresh machine:  `make run`  and  `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
OUT    ?= out
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: run test bench fuzz generate clean

# the main job's environment: kinegen and Dask (kinegen explore)
$(BIN)/kinegen: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[explore]'
	touch $@

# tests and benchmarks add pytest, ruff and the benchmark's baselines (CasADi, SymEngine: large)
$(VENV)/.dev: $(BIN)/kinegen
	$(BIN)/pip install --quiet -e '.[test,bench,explore]'
	touch $@

## run: build every model in models/ and solve every case; summary on screen, CSV + PNG in $(OUT)/
run: $(BIN)/kinegen
	$(BIN)/python -m kinegen.demo --out $(OUT)

## test: lint, then the whole test suite
test: $(VENV)/.dev
	$(BIN)/ruff check kinegen tests generated
	$(BIN)/python -m pytest -q -n auto --maxprocesses=4 --dist loadgroup

## bench: kinegen vs CasADi, SymEngine, naive SymPy, SciPy on chain-N and the excavator (BENCH_ARGS="--sizes 14 50 100")
bench: $(VENV)/.dev
	$(BIN)/python -m kinegen.bench $(BENCH_ARGS)

## fuzz: 10,000 fuzzed model files (Hypothesis), each ending in a ModelError naming file and entry; then
## hostile names, damaged modules and libraries, random input signals and command lines (issue 25)
fuzz: $(VENV)/.dev
	mkdir -p $(OUT)
	KINEGEN_FUZZ_EXAMPLES=$${KINEGEN_FUZZ_EXAMPLES:-10000} KINEGEN_FUZZ_REPORT=$(OUT)/fuzz.txt \
		$(BIN)/python -m pytest -q -s -p no:randomly tests/test_fuzz.py tests/test_fuzz_layers.py
	@cat $(OUT)/fuzz.txt

## generate: rebuild every committed module in generated/ from models/
generate: $(BIN)/kinegen
	$(BIN)/python -m kinegen.demo --regenerate-only

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
