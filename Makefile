# penaltyrun — common tasks. `make help` lists them.
PYTHON ?= python3
PIP ?= $(PYTHON) -m pip
PYTEST_ARGS ?=
WORKERS ?= 2

.PHONY: help install install-dev run test test-slow lint bench reproduce-tables clean

help:  ## list targets
	@grep -E '^[a-zA-Z_-]+:.*?## ' $(MAKEFILE_LIST) | awk 'BEGIN {FS = ":.*?## "}; {printf "  %-18s %s\n", $$1, $$2}'

install:  ## install penaltyrun (editable) with its runtime dependencies
	$(PIP) install -q -e .

install-dev:  ## install penaltyrun with test and lint tools
	$(PIP) install -q -e ".[dev]"

run: install  ## small default experiment end to end: optimize → Parquet → report
	$(PYTHON) -m penaltyrun.cli -m problem=zermelo param=diagonal,full runner.n_starts=4 \
		runner.workers=$(WORKERS) hydra.sweep.dir=outputs/quickstart
	$(PYTHON) -m penaltyrun.report_cli outputs/quickstart -o outputs/quickstart/report
	@echo "report: outputs/quickstart/report/report.md"

test: install-dev  ## run the default test suite (slow tests excluded)
	$(PYTHON) -m pytest -q $(PYTEST_ARGS)

test-slow: install-dev  ## run only the long tests
	$(PYTHON) -m pytest -q -m slow $(PYTEST_ARGS)

lint: install-dev  ## ruff
	$(PYTHON) -m ruff check penaltyrun tests bench

bench: install  ## benchmarks (ratios against references measured in the same run)
	$(PYTHON) bench/bench_zermelo.py
	@for f in bench/bench_attitude.py bench/bench_lowthrust.py; do \
		if [ -f $$f ]; then $(PYTHON) $$f || exit 1; fi; done

reproduce-tables: install  ## paper studies (default profiles) and the report
	$(PYTHON) -m penaltyrun.cli -m +experiment=zermelo_paper runner.workers=$(WORKERS) \
		hydra.sweep.dir=outputs/reproduce/zermelo
	$(PYTHON) -m penaltyrun.report_cli outputs/reproduce -o outputs/reproduce/report
	@echo "report: outputs/reproduce/report/report.md"

clean:  ## remove outputs and caches
	rm -rf outputs .pytest_cache .ruff_cache .hypothesis
