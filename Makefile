# Single entry point: `make demo` runs the default scene, `make test` runs every check.
PY := .venv/bin/python

.PHONY: setup demo test bench clean proto

setup:
	@bash tools/setup.sh

demo: setup
	$(PY) -m host_emulator run default --out out/default

test: setup
	$(PY) -m pytest -q -n 2 tests

bench: setup
	.venv/bin/pip install -q -e '.[bench]'
	$(PY) -m host_emulator bench-speed
	$(PY) -m host_emulator bench
	$(PY) -m host_emulator.batch --points 1000 --workers 1 2
	$(PY) -m host_emulator.bus.bench
	$(PY) -m tools.fwcheck report

# Regenerate the C headers, DBC and tables from protocol/definition.py (the test suite fails while they are stale).
proto: setup
	$(PY) -m protocol.generate

clean:
	rm -rf build out .pio
