# strapdown_ros developer entry points.  `make help` lists them.
#
#   make run    main job: the live pipeline on the default scenario into out/default + report
#   make test   the test command (ruff, then pytest); what CI runs (.ci/run)
#   make test-fast  ruff, then the tests that start no ROS process and are not slow
#
# Everything runs in .venv, created from pinned requirements by `make setup` (incremental).

SHELL := /bin/bash
.DEFAULT_GOAL := help

# Interpreter used to create .venv: python3.11 when present, else python3 (override: PYTHON=...).
PYTHON ?= $(shell command -v python3.11 >/dev/null 2>&1 && echo python3.11 || echo python3)

VENV         := .venv
VENV_ABS     := $(CURDIR)/$(VENV)
VPY          := $(VENV_ABS)/bin/python
SETUP_STAMP  := $(VENV)/.setup.stamp
PREFIX_STAMP := $(VENV)/.ament-prefix.stamp
TF2_STAMP    := $(VENV)/.tf2_msgs.stamp
REQUIREMENTS := requirements/base.txt requirements/dev.txt requirements/constraints.txt
CONSTRAINTS  := -c requirements/constraints.txt
# Files installed under .venv/share/strapdown_ros (re-run the prefix step when they change).
SHARE_FILES  := package.xml resource/strapdown_ros $(shell find config launch -type f 2>/dev/null)
PIP_QUIET    ?= -q

# What the venv needs to act as a ROS 2 Jazzy install prefix (rclpy comes from PyPI wheels).
export AMENT_PREFIX_PATH := $(VENV_ABS)
export PATH := $(VENV_ABS)/bin:$(PATH)
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export RMW_IMPLEMENTATION := rmw_fastrtps_cpp
export PIP_DISABLE_PIP_VERSION_CHECK := 1

.PHONY: help setup test test-fast test-minimum test-overlay lint bench figures mutation run generate \
	campaign clean distclean

help:
	@echo "make setup      create/update .venv (pinned deps, editable package, ament prefix)"
	@echo "make run        live pipeline on the default scenario into out/default, then its report"
	@echo "make campaign   100 Monte Carlo runs of the default flight on a local Dask cluster"
	@echo "make generate   the same scenario offline into out/default_offline, then its report"
	@echo "make test       ruff check + pytest, every test (the CI command)"
	@echo "make test-fast  ruff check + pytest -m \"not dds and not slow\" (no ROS process, rclpy blocked)"
	@echo "make test-minimum  the fast tests with the oldest supported libraries on Python 3.12 (slow)"
	@echo "make test-overlay  the fast tests in a stand-in of a Jazzy/noble system install (slow)"
	@echo "make lint       ruff check only"
	@echo "make bench      install the bench extras (pyins) and run every bench/bench_*.py"
	@echo "make figures    re-measure the docs' figures (tools/figures.py) into docs/figures_measured.json"
	@echo "make mutation   mutmut on the modules that carry the product's claims, fast tests"
	@echo "               (MODULE=core/method2.py: one module and its tests; survivors:"
	@echo "               .venv/bin/python tools/mutation.py core/method2.py --results)"
	@echo "make clean      remove outputs and caches; make distclean also removes .venv"
	@echo "PYTHON=$(PYTHON)"

setup: $(SETUP_STAMP) $(PREFIX_STAMP) $(TF2_STAMP)

$(SETUP_STAMP): $(REQUIREMENTS) setup.py setup.cfg
	@if [ ! -x "$(VPY)" ]; then \
	    echo "creating $(VENV) with $(PYTHON) ($$($(PYTHON) --version 2>&1))"; \
	    $(PYTHON) -m venv $(VENV); \
	fi
	$(VPY) -m pip install $(PIP_QUIET) --upgrade pip $(CONSTRAINTS)
	$(VPY) -m pip install $(PIP_QUIET) -r requirements/dev.txt $(CONSTRAINTS)
	$(VPY) -m pip install $(PIP_QUIET) --no-deps --no-build-isolation -e .
	@touch $@

$(PREFIX_STAMP): $(SETUP_STAMP) tools/install_ament_prefix.py $(SHARE_FILES)
	$(VPY) tools/install_ament_prefix.py --symlink
	@touch $@

# tf2_msgs/msg/TFMessage (not in the ROS PyPI wheels) built into .venv for live TF; needs cmake
# and a C compiler, ~1 min. Without them it says why and setup goes on (live TF off).
$(TF2_STAMP): $(SETUP_STAMP) tools/build_tf2_msgs.py requirements/tf2_build.txt
	$(VPY) tools/build_tf2_msgs.py --optional
	@touch $@

lint: setup
	$(VPY) -m ruff check .

# Lint and tests both run; the target fails if either failed. The tests without ROS processes
# run on two workers (as test-fast), then the dds tests one at a time (each starts processes
# over DDS); a part with nothing selected (pytest's exit status 5) is no failure.
test: setup
	@lint=0; $(VPY) -m ruff check . || lint=$$?; \
	$(VPY) -m pytest -m "not dds" $(FAST_WORKERS) $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc != 0 ] && [ $$rc != 5 ]; then exit $$rc; fi; \
	$(VPY) -m pytest -m dds $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc != 0 ] && [ $$rc != 5 ]; then exit $$rc; fi; \
	if [ $$lint != 0 ]; then echo "ruff check failed (see above)"; exit $$lint; fi

# Compiled modules and pytest's rewritten test modules are cached in __pycache__ (git-ignored)
# even when the environment sets PYTHONDONTWRITEBYTECODE: each xdist worker would otherwise
# compile the package and rewrite every test module again (measured: 8 s of CPU per worker).
test test-fast: export PYTHONDONTWRITEBYTECODE :=

# The fast tier: no test that starts ROS processes (marker dds, set automatically by
# test/tiers.py; rclpy is then blocked in pytest and its children) and none marked slow.
FAST_MARKERS := not dds and not slow
# two workers, each test file on one of them (module fixtures built once)
FAST_WORKERS := -n 2 --dist loadfile
test-fast: setup
	@lint=0; $(VPY) -m ruff check . || lint=$$?; \
	$(VPY) -m pytest -m "$(FAST_MARKERS)" $(FAST_WORKERS) $(PYTEST_ARGS) || exit $$?; \
	if [ $$lint != 0 ]; then echo "ruff check failed (see above)"; exit $$lint; fi

# --- Supported versions, measured (slow; not part of make test) ------------------------------
# Python 3.12 (Ubuntu 24.04's); override with MIN_PYTHON=/path/to/python3.12.
MIN_PYTHON   ?= python3.12
ROS_PINS      = grep -E '^(ros-|pip==|setuptools==)' requirements/constraints.txt
# Never build these from source (a floor without a cp312 wheel is not a floor).
BINARY_ONLY  := numpy,scipy,numba,llvmlite,matplotlib,contourpy,kiwisolver,pillow,pydantic-core,pyarrow
FAST_PYTEST   = -m "$(FAST_MARKERS)" -p no:cacheprovider -q $(PYTEST_ARGS)

# noble's matplotlib 3.6.3 (the minimum) has no cp312 wheel on PyPI: built once into
# .noble-wheels against the system FreeType and Qhull (apt-get install libfreetype-dev
# libqhull-dev pkg-config); test-minimum and test-overlay install it from there.
NOBLE_WHEELS  := $(CURDIR)/.noble-wheels
MPL_WHEEL     := $(NOBLE_WHEELS)/.matplotlib-3.6.3.stamp
$(MPL_WHEEL):
	mkdir -p $(NOBLE_WHEELS)
	printf '[libs]\nsystem_freetype = true\nsystem_qhull = true\n' > $(NOBLE_WHEELS)/mplsetup.cfg
	MPLSETUPCFG=$(NOBLE_WHEELS)/mplsetup.cfg $(MIN_PYTHON) -m pip wheel $(PIP_QUIET) --no-deps \
	    -w $(NOBLE_WHEELS) matplotlib==3.6.3
	@touch $@

# The oldest supported version of every runtime library (requirements/minimum.txt, the table of
# strapdown_ros/requirements_check.py), the ROS wheels of constraints.txt, the test tools at
# their newest; then the fast tests. A fresh .venv-min each time.
MIN_VENV := $(CURDIR)/.venv-min
test-minimum: $(MPL_WHEEL)
	rm -rf $(MIN_VENV) && $(MIN_PYTHON) -m venv $(MIN_VENV)
	$(ROS_PINS) > $(MIN_VENV)/ros-pins.txt
	$(MIN_VENV)/bin/python -m pip install $(PIP_QUIET) --upgrade pip -c $(MIN_VENV)/ros-pins.txt
	$(MIN_VENV)/bin/python -m pip install $(PIP_QUIET) --only-binary=$(BINARY_ONLY) \
	    --find-links $(NOBLE_WHEELS) \
	    -r requirements/dev.txt -c requirements/minimum.txt -c $(MIN_VENV)/ros-pins.txt
	$(MIN_VENV)/bin/python -m pip install $(PIP_QUIET) --no-deps --no-build-isolation -e .
	$(MIN_VENV)/bin/python tools/install_ament_prefix.py --symlink
	$(MIN_VENV)/bin/python -m pip freeze --exclude-editable > $(MIN_VENV)/freeze.txt
	AMENT_PREFIX_PATH=$(MIN_VENV) PATH=$(MIN_VENV)/bin:$$PATH \
	    $(MIN_VENV)/bin/python -m pytest $(FAST_PYTEST)

# A stand-in of the documented system install (README, "Using it on a real ROS 2 Jazzy
# install"): .venv-noble holds what apt and /opt/ros/jazzy give on Ubuntu 24.04 (the noble
# versions of numpy, scipy, PyYAML, matplotlib, pydantic 1.10, pytest; test/data/rosdep/
# noble_apt.yaml) and the ROS wheels; .venv-overlay sees it as system site-packages (a .pth
# calling site.addsitedir, so that its own .pth files run as a system site's do: the ROS wheels'
# library loader; --system-site-packages reaches only the base interpreter) and gets the one pip
# command (requirements/ros-overlay.txt); then the fast tests, with the test tools pip adds and
# the ROS libraries on LD_LIBRARY_PATH (what sourcing /opt/ros/jazzy/setup.bash does).
NOBLE_VENV    := $(CURDIR)/.venv-noble
OVERLAY_VENV  := $(CURDIR)/.venv-overlay
NOBLE_PYTHON_LIBS := numpy==1.26.4 scipy==1.11.4 PyYAML==6.0.1 matplotlib==3.6.3 \
	pydantic==1.10.14 pytest==7.4.4 pytest-timeout==2.2.0 setuptools==68.1.2 wheel==0.42.0
test-overlay: $(MPL_WHEEL)
	rm -rf $(NOBLE_VENV) $(OVERLAY_VENV) && $(MIN_PYTHON) -m venv $(NOBLE_VENV)
	$(ROS_PINS) | grep -v '^setuptools==' > $(NOBLE_VENV)/ros-pins.txt
	$(NOBLE_VENV)/bin/python -m pip install $(PIP_QUIET) --find-links $(NOBLE_WHEELS) \
	    $(NOBLE_PYTHON_LIBS) -c $(NOBLE_VENV)/ros-pins.txt \
	    ros-jazzy-rclpy ros-jazzy-common-interfaces ros-jazzy-rmw-fastrtps-cpp
	$(MIN_PYTHON) -m venv $(OVERLAY_VENV)
	$(NOBLE_VENV)/bin/python -c 'import site; print(f"import site; site.addsitedir({site.getsitepackages()[0]!r})")' \
	    > $$($(OVERLAY_VENV)/bin/python -c 'import site; print(site.getsitepackages()[0])')/noble-system.pth
	$(OVERLAY_VENV)/bin/python -m pip install $(PIP_QUIET) -r requirements/ros-overlay.txt
	$(OVERLAY_VENV)/bin/python -m pip freeze --exclude-editable > $(OVERLAY_VENV)/freeze.txt
	$(OVERLAY_VENV)/bin/python -m pip install $(PIP_QUIET) mpmath ambiance mcap-ros2-support ruff
	$(OVERLAY_VENV)/bin/python -m pip install $(PIP_QUIET) --no-deps --no-build-isolation -e .
	$(OVERLAY_VENV)/bin/python tools/install_ament_prefix.py --symlink
	AMENT_PREFIX_PATH=$(OVERLAY_VENV) PATH=$(OVERLAY_VENV)/bin:$$PATH \
	    LD_LIBRARY_PATH=$$($(NOBLE_VENV)/bin/python -c \
	        'import ros_wheels_bootstrapper as b; print(b.get_ros_paths())') \
	    $(OVERLAY_VENV)/bin/python -m pytest $(FAST_PYTEST)

# Benchmark-only dependencies (pyins for bench/bench_peers.py), pinned in requirements/bench.txt
# and installed into .venv on top of the locked environment; `make test` does not need them.
BENCH_REQUIREMENTS := requirements/bench.txt
BENCH_STAMP        := $(VENV)/.bench.stamp

$(BENCH_STAMP): $(SETUP_STAMP) $(BENCH_REQUIREMENTS) requirements/constraints.txt
	$(VPY) -m pip install $(PIP_QUIET) -r $(BENCH_REQUIREMENTS) $(CONSTRAINTS)
	@touch $@

bench: setup $(BENCH_STAMP)
	@found=0; \
	for f in bench/bench_*.py; do \
	    [ -e "$$f" ] || continue; found=1; \
	    echo "== $$f"; $(VPY) "$$f" || exit $$?; \
	done; \
	[ $$found = 1 ] || echo "no bench/bench_*.py yet"

# The docs' figures that a command re-measures (docs/figures.yaml names the command of every
# figure), written with the commit and load average into docs/figures_measured.json;
# test/test_figures.py checks the docs quote them. FIGURES_ARGS="--only serialize_speedup" etc.
FIGURES_ARGS ?=
figures: setup
	$(VPY) tools/figures.py $(FIGURES_ARGS)

# Mutation testing (mutmut, configured in setup.cfg [mutmut]): mutants of the modules listed
# there, each run against the fast tests that cover it. The whole set takes hours on 2 cores;
# MUTATION_ARGS narrows it, e.g. MUTATION_ARGS="strapdown_ros.core.allan*". Results:
# `.venv/bin/mutmut results`, a survivor's diff: `.venv/bin/mutmut show NAME`.
MUTATION_ARGS ?=
# MODULE=core/method2.py: that module against the tests that cover it (tools/mutation.py), in a
# scratch copy under out/mutation/; without MODULE, setup.cfg's whole list.
MODULE ?=
mutation: setup
	$(VPY) -m pip install -q -r requirements/mutation.txt
	$(VPY) tools/mutation.py $(MODULE) $(if $(MUTATION_ARGS),-- $(MUTATION_ARGS))

# The main job: the live pipeline (nodes as processes over DDS, recorded into a bag) on the
# default 10-minute flight at RUN_RATE_FACTOR x real time, then the report of the bag.
RUN_RATE_FACTOR ?= 5
run: setup
	strapdown-sim run config/scenarios/default.yaml --out out/default --force \
	    --rate-factor $(RUN_RATE_FACTOR)
	strapdown-sim report out/default

# The same scenario computed offline (no ROS graph): identical messages, ~10 s.
generate: setup
	strapdown-sim generate config/scenarios/default.yaml --out out/default_offline --force
	strapdown-sim report out/default_offline

# A Monte Carlo campaign: 100 realizations of the default flight (tactical IMU errors, bending)
# on a local Dask cluster; resumable (same --out), report in out/campaign_default/report/.
CAMPAIGN_RUNS ?= 100
campaign: setup
	strapdown-sim campaign config/scenarios/default.yaml --runs $(CAMPAIGN_RUNS) \
	    --out out/campaign_default

clean:
	rm -rf out build install log .pytest_cache .ruff_cache *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV) .venv-min .venv-noble .venv-overlay .noble-wheels

# The benchmark suite (docs/suite.md): fixed-seed scenarios generated into out/suite/<name>.
# SUITE_ARGS passes options to generate, e.g. SUITE_ARGS="--duration 60".
SUITE := config/suite/car_city.yaml config/scenarios/default.yaml config/suite/rtk_survey.yaml \
         config/suite/static_alignment.yaml config/suite/misalignment.yaml config/suite/timing.yaml
SUITE_ARGS ?=
.PHONY: suite
suite: setup
	@mkdir -p out/suite
	@for f in $(SUITE); do \
	    name=$$(basename $$f .yaml); echo "== $$name"; \
	    $(VENV_ABS)/bin/strapdown-sim generate $$f --out out/suite/$$name --force --quiet \
	        $(SUITE_ARGS) || exit $$?; \
	done
	@echo "suite bags in out/suite/ (score one: strapdown-sim score out/suite/NAME --topic ...)"
