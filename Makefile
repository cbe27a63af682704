# hexacal developer tasks. `make test` and `make demo` set up .venv first.
PY ?= python3
VENV ?= .venv
VENV_PY := $(VENV)/bin/python
SRC := ros2_ws/src
PACKAGES := hexacal_msgs_py hexacal_identify hexacal_driver
# Extra pytest arguments, e.g. make test PYTEST_ARGS="-m 'not slow'"
PYTEST_ARGS ?=
# Test processes (pytest-xdist), each test file whole on one of them (its module fixtures
# shared); each process claims a ROS domain of its own (tests/conftest.py).  1: one process.
TEST_WORKERS ?= 2
PARALLEL := $(if $(filter 1,$(TEST_WORKERS)),,-n $(TEST_WORKERS) --dist loadfile)
# The unit tier: the packages' own tests (no DDS, no processes).
UNIT_TESTS := $(foreach p,$(PACKAGES),$(SRC)/$(p)/test)

STAMP := $(VENV)/.hexacal-setup.stamp
# Anything that changes what `make setup` installs re-runs it.
SETUP_INPUTS := Makefile requirements.txt requirements-dev.txt \
	$(foreach p,$(PACKAGES),$(SRC)/$(p)/setup.py $(SRC)/$(p)/setup.cfg \
		$(SRC)/$(p)/package.xml $(SRC)/$(p)/resource/$(p)) \
	$(wildcard $(SRC)/*/launch/*.launch.py)

# Editable (PEP 660) installs do not install setup.py data_files, so the
# ament index markers, package.xml and launch files would be missing from the
# venv. This symlinks every data_files entry into the venv prefix, as
# `colcon build --symlink-install` does; with AMENT_PREFIX_PATH=sys.prefix,
# ament_index_python then finds the packages.
define LINK_DATA_FILES
import os, sys
from pathlib import Path
from distutils.core import run_setup

prefix = Path(sys.prefix)
for source in (Path(arg).resolve() for arg in sys.argv[1:]):
    cwd = os.getcwd()
    os.chdir(source)
    try:
        dist = run_setup('setup.py', stop_after='init')
    finally:
        os.chdir(cwd)
    share = prefix / 'share' / dist.get_name()
    if share.is_dir():  # drop links of an earlier setup, e.g. of deleted launch files
        for link in [p for p in share.rglob('*') if p.is_symlink()]:
            link.unlink()
    for destination, files in dist.data_files or []:
        (prefix / destination).mkdir(parents=True, exist_ok=True)
        for name in files:
            link = prefix / destination / Path(name).name
            if link.is_symlink() or link.exists():
                link.unlink()
            link.symlink_to(source / name)
endef
export LINK_DATA_FILES

.PHONY: setup test test-fast lint demo bench clean

setup: $(STAMP)

$(VENV_PY):
	$(PY) -m venv $(VENV)

$(STAMP): $(SETUP_INPUTS) | $(VENV_PY)
	$(VENV_PY) -m pip install --quiet -r requirements-dev.txt
	$(VENV_PY) -m pip install --quiet $(foreach p,$(PACKAGES),-e $(SRC)/$(p))
	$(VENV_PY) -c "$$LINK_DATA_FILES" $(addprefix $(SRC)/,$(PACKAGES))
	touch $@

# Everything, the lint set included (tests marked linter): the CI command (.ci/run).
test: setup
	sh scripts/ensure_chromium.sh
	$(VENV_PY) -m pytest $(PARALLEL) $(PYTEST_ARGS)

# The fast loop: the unit tier without the tests marked slow (about a minute on 2 cores).
test-fast: setup
	$(VENV_PY) -m pytest $(PARALLEL) $(UNIT_TESTS) -m 'not slow' $(PYTEST_ARGS)

# ament_flake8 and ament_pep257 on each package, mypy on all three: the tests marked linter.
lint: setup
	$(VENV_PY) -m pytest $(UNIT_TESTS) tests/test_mypy_core.py -m linter $(PYTEST_ARGS)

demo: setup
	$(VENV)/bin/hexacal demo

bench: setup
	$(VENV_PY) benchmarks/bench_identification.py
	$(VENV_PY) benchmarks/bench_startup.py
	$(VENV_PY) benchmarks/bench_service.py
	$(VENV_PY) benchmarks/bench_decode.py
	$(VENV_PY) benchmarks/bench_load.py --minutes 1
	$(VENV_PY) benchmarks/bench_load.py --minutes 1 --busy-core

clean:
	rm -rf $(VENV) build install log ros2_ws/build ros2_ws/install ros2_ws/log \
		out .pytest_cache .hypothesis .mypy_cache
	find . -path ./.git -prune -o \( -name __pycache__ -o -name '*.egg-info' \
		-o -name .pytest_cache -o -name .hypothesis \) -prune -exec rm -rf {} +
