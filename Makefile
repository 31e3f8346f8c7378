# Two commands for a fresh machine: `make demo` and `make test` (each installs what it needs first).
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: setup demo test lint bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml scripts/setup.sh
	VENV=$(VENV) bash scripts/setup.sh

demo: setup
	$(BIN)/cuboids demo -o out/demo

test: setup
	$(BIN)/ruff check .
	$(BIN)/pytest -q

bench: setup
	$(BIN)/python benchmarks/bench_fit.py

clean:
	rm -rf out build dist *.egg-info .pytest_cache .ruff_cache
