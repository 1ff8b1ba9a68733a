# MAGNA: the two commands people need are `make run` and `make test`; both set up first.
SHELL := /bin/bash
.DEFAULT_GOAL := help

.PHONY: help setup run test test-faults lint bench clean

help:  ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-11s %s\n", $$1, $$2}'

setup:  ## install Debian packages, the venv and build the catkin workspace (quick when done)
	@bash scripts/setup.sh

# The default batch: two UAVs crossing the gym's central obstacles with ORCA-3D, three simulations,
# headless, as fast as the machine goes. Runs append to the dataset (nothing is overwritten).
# RUN_ARGS adds to these defaults: an option it names overrides the default (magna run keeps the
# last value given), and a dataset policy it names (--overwrite, --skip-save) replaces --append.
RUN_DEFAULTS := --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA --n-iter 3 --rtf max
RUN_POLICY := $(if $(filter --append --overwrite --skip-save --no-data,$(RUN_ARGS)),,--append)

run: setup  ## the main job: a default batch of simulations (RUN_ARGS="--n-iter 1 ..." adds to the defaults)
	@./magna run $(RUN_DEFAULTS) $(RUN_POLICY) $(RUN_ARGS)

test: setup  ## linters, unit tests (pytest) and integration tests (gtest, rostest), one summary
	@bash scripts/test.sh

# The slow fault run, kept out of `make test`: 50 simulations in one batch, the Master's memory and
# descriptors, orphans and ~/.ros watched (tests/faults/endurance.py prints the figures).
test-faults: setup  ## the endurance batch (50 simulations; long, not part of make test)
	@bash scripts/with_env.sh python -m pytest -q -s -p no:cacheprovider tests/faults/endurance.py

lint: setup  ## ruff, catkin_lint, mypy and the layering check only
	@bash scripts/test.sh --lint-only

bench: setup  ## benchmarks: print figures, never fail on a time
	@bash scripts/with_env.sh bash -c 'for b in bench/*.py; do [ -e "$$b" ] || continue; echo "== $$b"; python "$$b" || exit 1; done'

clean:  ## remove build products (keeps .venv)
	rm -rf build devel install logs .catkin_tools
