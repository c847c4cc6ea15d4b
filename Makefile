# penaltyrun — common tasks. `make help` lists them.
#
# Every target runs in a virtual environment of its own, $(VENV) (default .venv), made on
# first use with $(BOOTSTRAP_PYTHON) -m venv. So `make run` and `make test` work where the
# system Python refuses `pip install` (externally managed, PEP 668: current Debian, Ubuntu).
# `make VENV=/path/to/env ...` uses another environment; `make VENV= PYTHON=python3 ...`
# uses a Python you manage yourself (no virtual environment).
VENV ?= .venv
BOOTSTRAP_PYTHON ?= python3
ifeq ($(strip $(VENV)),)
PYTHON ?= python3
VENV_PYTHON :=
else
PYTHON ?= $(VENV)/bin/python
VENV_PYTHON := $(VENV)/bin/python
endif
PIP ?= $(PYTHON) -m pip
PYTEST_ARGS ?=
# Test processes of `make test` (pytest-xdist; auto: one per core). Each test file runs
# whole in one process, so a module's expensive fixtures are built once.
TEST_WORKERS ?= auto
WORKERS ?= 2

.PHONY: help venv install install-dev install-locked run test test-random test-slow test-reference lint bench \
	reproduce-tables reproduce-zermelo reproduce-attitude reproduce-lowthrust referee-zermelo \
	referee-attitude report docs docs-serve docs-results check-docs lock study-list clean

help:  ## list targets
	@grep -E '^[a-zA-Z_%-]+:.*?## ' $(MAKEFILE_LIST) | awk 'BEGIN {FS = ":.*?## "}; {printf "  %-18s %s\n", $$1, $$2}'

venv: $(VENV_PYTHON)  ## create the virtual environment $(VENV) (done by every target)

$(VENV_PYTHON):
	@$(BOOTSTRAP_PYTHON) -m venv $(VENV) || { echo "make: cannot create the virtual" \
		"environment $(VENV) with '$(BOOTSTRAP_PYTHON) -m venv' (Debian/Ubuntu:" \
		"apt-get install python3-venv)" >&2; rm -rf $(VENV); exit 1; }
	$(PYTHON) -m pip install -q --upgrade pip

# Installing is done once: a stamp file in the environment records it, and every target
# that needs penaltyrun installed depends on the stamp, which is remade only when
# pyproject.toml changes (or the environment is new). `make install` / `make install-dev`
# named on the command line always reinstall.
STAMP_DIR := $(if $(strip $(VENV)),$(VENV),.)
INSTALLED := $(STAMP_DIR)/.installed
INSTALLED_DEV := $(STAMP_DIR)/.installed-dev
ifneq ($(filter install,$(MAKECMDGOALS)),)
.PHONY: $(INSTALLED)
endif
ifneq ($(filter install-dev,$(MAKECMDGOALS)),)
.PHONY: $(INSTALLED_DEV)
endif

install: $(INSTALLED)  ## install penaltyrun (editable) with its runtime dependencies

$(INSTALLED): pyproject.toml | $(VENV_PYTHON)
	$(PIP) install -q -e .
	@touch $@

install-dev: $(INSTALLED_DEV)  ## install penaltyrun with test, lint and documentation tools

$(INSTALLED_DEV): pyproject.toml | $(VENV_PYTHON)
	$(PIP) install -q -e ".[dev]"
	@touch $@ $(INSTALLED)

# requirements.lock pins every package version that made the committed study data
# (`make lock` writes it from this environment). LOCKED=true makes the study and reproduce
# targets install exactly those versions first, so a regenerated study runs on the same
# numpy / scipy / numba / pyswarms / cma as the committed one.
LOCK_FILE ?= requirements.lock
LOCKED ?= false
ifeq ($(LOCKED),true)
STUDY_INSTALL := install-locked
else
STUDY_INSTALL := install
endif

install-locked: $(VENV_PYTHON)  ## install the exact versions of requirements.lock, then penaltyrun (editable)
	$(PIP) install -q -r $(LOCK_FILE)
	$(PIP) install -q --no-deps -e .
	@touch $(INSTALLED)

lock: install-dev  ## pin this environment's versions of penaltyrun's dependencies into requirements.lock (uv)
	$(PYTHON) -m pip freeze --exclude-editable > $(LOCK_FILE).constraints
	$(PYTHON) -m uv pip compile pyproject.toml --extra dev --extra docs --extra dask \
		--constraint $(LOCK_FILE).constraints --python $(PYTHON) --no-header \
		--output-file $(LOCK_FILE) --quiet; status=$$?; rm -f $(LOCK_FILE).constraints; exit $$status
	@echo "wrote $(LOCK_FILE)"

# CMA-ES spends exactly optimizer.max_evals per start (no early stop), so the two maps have
# equal budgets and the report's map-vs-map test runs (a stall rule would make them differ).
run: install  ## small default experiment end to end: optimize → Parquet → report
	$(PYTHON) -m penaltyrun.cli -m problem=zermelo param=diagonal,full optimizer=cmaes \
		optimizer.max_evals=2000 runner.n_starts=10 runner.workers=$(WORKERS) \
		hydra.sweep.dir=outputs/quickstart
	$(PYTHON) -m penaltyrun.report_cli outputs/quickstart -o outputs/quickstart/report
	@echo "report: outputs/quickstart/report/report.md (the verdict's 'equal budget' column:"
	@echo "diagonal vs full, CMA-ES, 2000 evaluations per start)"

test: install-dev  ## run the default test suite (slow tests excluded), one test process per core
	$(PYTHON) -m pytest -q -n $(TEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

# The default suite in one process, test files and the tests inside each in a random order
# (pytest-random-order): an import-order dependence shows here whatever the file order of
# `make test`. The seed is printed; RANDOM_SEED=N repeats an order.
ifndef RANDOM_SEED
RANDOM_SEED := $(shell python3 -c "import random; print(random.randrange(10**6))")
endif

test-random: install-dev  ## the default suite serially in a random module order (seed printed; RANDOM_SEED=N repeats it)
	@echo "test-random: --random-order-seed=$(RANDOM_SEED)"
	$(PYTHON) -m pytest -q -p no:cacheprovider --random-order-bucket=module \
		--random-order-seed=$(RANDOM_SEED) $(PYTEST_ARGS)

test-slow: install-dev  ## run only the long tests
	$(PYTHON) -m pytest -q -m slow $(PYTEST_ARGS)

test-reference: install-dev  ## run the very long reference checks (hours; not in CI)
	$(PYTHON) -m pytest -q -m reference $(PYTEST_ARGS)

lint: install-dev  ## ruff and the layering contract (import-linter, [tool.importlinter] in pyproject.toml)
	$(PYTHON) -m ruff check penaltyrun tests bench examples
	$(PYTHON) -c "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"

bench: install  ## benchmarks (ratios against references measured in the same run)
	$(PYTHON) bench/bench_zermelo.py
	@for f in bench/bench_attitude.py bench/bench_lowthrust.py bench/bench_first_eval.py \
		bench/bench_swarm.py bench/swarm_model.py bench/bench_cutoff.py bench/bench_heyoka.py \
		bench/bench_lqr.py bench/bench_mpc.py bench/bench_overhead.py bench/bench_cmaes.py; do \
		if [ -f $$f ]; then $(PYTHON) $$f || exit 1; fi; done
	$(PYTHON) bench/bench_decode.py
	$(PYTHON) bench/geagsp_conditioning.py

REPRO ?= outputs/reproduce
RESUME ?= false
SWEEP = $(PYTHON) -m penaltyrun.cli -m runner.workers=$(WORKERS) runner.report=false \
	runner.resume=$(RESUME)

reproduce-zermelo: $(STUDY_INSTALL)  ## Zermelo study: 4 maps × PSO and DE × 10 starts (≈ 1 min)
	$(SWEEP) +experiment=zermelo_paper hydra.sweep.dir=$(REPRO)/zermelo

reproduce-attitude: $(STUDY_INSTALL)  ## attitude Tables 1-2 + robustness, DE check of diagonal, t_f sweep
	$(SWEEP) +experiment=attitude_paper hydra.sweep.dir=$(REPRO)/attitude
	$(SWEEP) +experiment=attitude_de_check hydra.sweep.dir=$(REPRO)/attitude_de_check
	$(SWEEP) +experiment=attitude_horizon hydra.sweep.dir=$(REPRO)/attitude_horizon

reproduce-lowthrust: $(STUDY_INSTALL)  ## low-thrust Tables 3-5: K = I baselines, generic law, Q-law
	$(SWEEP) +experiment=lowthrust_baseline hydra.sweep.dir=$(REPRO)/lowthrust_baseline
	$(SWEEP) +experiment=lowthrust_cap hydra.sweep.dir=$(REPRO)/lowthrust_cap
	$(SWEEP) +experiment=lowthrust_generic hydra.sweep.dir=$(REPRO)/lowthrust_generic
	$(SWEEP) +experiment=lowthrust_qlaw hydra.sweep.dir=$(REPRO)/lowthrust_qlaw
	$(SWEEP) +experiment=lowthrust_qlaw_minfuel hydra.sweep.dir=$(REPRO)/lowthrust_qlaw_minfuel

referee-zermelo: $(STUDY_INSTALL)  ## referee study, Zermelo: 4 maps × pso/de/cmaes × 30 starts at 2000 evaluations + grid
	$(SWEEP) +experiment=referee_zermelo hydra.sweep.dir=$(REPRO)/referee_zermelo
	$(SWEEP) problem=zermelo param=diagonal,geagsp optimizer=grid runner.n_starts=1 \
		hydra.sweep.dir=$(REPRO)/referee_zermelo/grid
	$(PYTHON) -m penaltyrun.report_cli $(REPRO)/referee_zermelo -o $(REPRO)/referee_zermelo/report

referee-attitude: $(STUDY_INSTALL)  ## referee study, attitude: 2 laws × 2 manoeuvres × 4 maps × pso/de/cmaes × 30 starts at 3000 evaluations, + diagonal check (≈ 1.5 h)
	$(SWEEP) +experiment=referee_attitude hydra.sweep.dir=$(REPRO)/referee_attitude
	$(SWEEP) +experiment=referee_attitude_diagonal \
		hydra.sweep.dir=$(REPRO)/referee_attitude/diagonal_check
	$(PYTHON) -m penaltyrun.report_cli $(REPRO)/referee_attitude -o $(REPRO)/referee_attitude/report

report:  ## report of everything under $(REPRO)
	$(PYTHON) -m penaltyrun.report_cli $(REPRO) -o $(REPRO)/report
	@echo "report: $(REPRO)/report/report.md"

reproduce-tables: reproduce-zermelo reproduce-attitude reproduce-lowthrust  ## all paper studies, then the report (RESUME=true continues an interrupted run)
	$(MAKE) report REPRO=$(REPRO)

docs: install-dev  ## build the documentation site strictly (every warning an error) into site/
	NO_MKDOCS_2_WARNING=1 $(PYTHON) -m mkdocs build --strict --quiet
	@echo "site: site/index.html"

docs-serve: install-dev  ## serve the documentation at http://127.0.0.1:8000 while editing
	NO_MKDOCS_2_WARNING=1 $(PYTHON) -m mkdocs serve

docs-results: install-dev  ## regenerate docs/results/*.md and the README's answer table from studies/*
	$(PYTHON) -m penaltyrun.docsgen results

check-docs: install-dev  ## fail if a generated number in docs/results or the README differs from studies/*
	$(PYTHON) -m penaltyrun.docsgen check

study-list:  ## list the studies (studies/<name>/study.yaml)
	@$(PYTHON) -m penaltyrun.docsgen study list

ONLY ?=
EXTEND ?= false
study-%: $(STUDY_INSTALL)  ## run study <name> (resumable: RESUME=true; ONLY=<subdir> EXTEND=true: one command added to the committed data), merge into studies/<name>/
	$(PYTHON) -m penaltyrun.docsgen study run $* --workers $(WORKERS) --resume $(RESUME) \
		$(foreach s,$(ONLY),--only $(s)) $(if $(filter true,$(EXTEND)),--extend)

clean:  ## remove outputs and caches (not the virtual environment: `rm -rf .venv`)
	rm -rf outputs site .pytest_cache .ruff_cache .hypothesis
