# Two commands for a user: `make demo` and `make test`. Both install what is missing first.
SHELL := /bin/bash
ROOT := $(CURDIR)
RUN := source $(ROOT)/env.sh &&
PYTEST_ARGS ?=

.PHONY: setup demo test test-ray test-dem-live unit integration lint bench shell dem-tables clean

setup:
	@scripts/setup.sh

demo: setup
	@$(RUN) rosrun ow_mission mission --wait-figures

test: setup lint
	@$(RUN) python -m pytest -n 2 --dist loadscope tests $(PYTEST_ARGS)

# The campaign on a local Ray instance, which make test skips (too heavy beside the suite).
test-ray: setup
	@$(RUN) OW_RAY_TESTS=1 python -m pytest tests/integration/test_campaign.py $(PYTEST_ARGS)

# The live DEM digs in the simulation and in the running stack (minutes of wall time each),
# which make test skips.
test-dem-live: setup
	@$(RUN) OW_DEM_LIVE_TESTS=1 python -m pytest tests/unit/ow_sim_bullet/test_live_dem_sample.py \
	  tests/integration/test_dem_live.py $(PYTEST_ARGS)

unit: setup
	@$(RUN) python -m pytest -n 2 tests/unit $(PYTEST_ARGS)

integration: setup
	@$(RUN) python -m pytest -n 2 --dist loadscope tests/integration $(PYTEST_ARGS)

lint: setup
	@$(RUN) ruff check src tests bench scripts && ruff format --check src tests bench scripts \
	  && mypy

bench: setup
	@$(RUN) for b in bench/*.py; do \
	  if [ "$$b" = bench/cosim.py ] && [ -z "$$OW_BENCH_COSIM" ]; then continue; fi; \
	  python $$b || exit 1; done

# An interactive shell with the workspace environment (venv, devel space, ROS_HOSTNAME, ROS_HOME).
shell: setup
	@bash --rcfile <(echo 'source ~/.bashrc 2>/dev/null; source $(ROOT)/env.sh; PS1="(ow) $$PS1"')

dem-tables: setup
	@$(RUN) python -m ow_dem_bridge.make_tables

clean:
	rm -rf build devel .ros .pytest_cache .mypy_cache .ruff_cache
