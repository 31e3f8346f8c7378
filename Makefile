# Two commands for a fresh machine: `make demo` and `make test` (each installs what it needs first).
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: setup demo test wheel-check lint bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml scripts/setup.sh
	VENV=$(VENV) bash scripts/setup.sh

demo: setup
	$(BIN)/cuboids demo -o out/demo

test: setup
	$(BIN)/ruff check .
	$(BIN)/pytest -q

# Build the wheel, install it into a fresh venv outside the checkout, run the demo and a few fits there.
wheel-check:
	bash scripts/wheel_check.sh

bench: setup
	$(BIN)/python benchmarks/bench_fit.py

clean:
	rm -rf out build dist *.egg-info .pytest_cache .ruff_cache
