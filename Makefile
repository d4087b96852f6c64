# Single entry point: `make demo` runs the default scene, `make test` runs every check.
PY := .venv/bin/python

# Python code the linters hold to the style and typing rules (config in pyproject.toml)
LINT_PATHS := host_emulator metacell_common protocol metacell_tools tests

.PHONY: setup demo lint test bench clean proto

setup:
	@bash tools/setup.sh

demo: setup
	$(PY) -m host_emulator run default --out out/default

# each linter fails the run on its own; pytest runs only when all four pass (lint-imports: the layers and the
# forbidden imports, contracts in pyproject.toml)
lint: setup
	.venv/bin/ruff check $(LINT_PATHS)
	.venv/bin/ruff format --check $(LINT_PATHS)
	.venv/bin/mypy
	.venv/bin/lint-imports --no-cache

test: lint
	$(PY) -m pytest -q -n 2 tests

bench: setup
	.venv/bin/pip install -q -e '.[bench]'
	$(PY) -m host_emulator bench-speed
	$(PY) -m host_emulator bench
	$(PY) -m host_emulator.benchmarks.batch --points 1000 --workers 1 2
	$(PY) -m host_emulator.benchmarks.bus
	$(PY) -m metacell_tools.fwcheck report

# After editing protocol/definition.py: regenerate the C headers, DBC and tables, and (a unit or limit changes the
# library's behaviour) the native golden vectors. The test suite fails while either is stale.
proto: setup
	$(PY) -m protocol.generate
	$(PY) -m metacell_tools.fwcheck golden-header

clean:
	rm -rf build out .pio
