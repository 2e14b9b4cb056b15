# DynaBARN on MuJoCo. `make demo` runs the main job, `make test` runs the tests.
# Both create the virtual environment in .venv when it is missing, with the exact versions
# of requirements.lock (pyproject.toml keeps ranges for people who pip install into their
# own environment); `make lock` resolves the ranges anew and rewrites the lock.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
DOCS_STAMP := $(VENV)/.installed-docs
LOCK := requirements.lock
# The extras the tests exercise; the lock covers the package and all of them.
EXTRAS := test,ray,learn,ros,docs,gpu

.PHONY: install demo worlds test test-fast docs docs-serve lint format bench clean system-deps ros-deps ros-nav-deps ros-nav ros-teb-deps ros-teb ros2-deps ros2-core nav2-deps nav2 lock verify-golden readme

# The package and what running it needs.
$(STAMP): pyproject.toml $(LOCK)
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c $(LOCK) -e .
	touch $(STAMP)

# Plus the test tools and the optional extras the tests exercise (Ray, PyTorch CPU, Gymnasium,
# rosbags, MkDocs).
$(TEST_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -c $(LOCK) -e '.[$(EXTRAS)]'
	touch $(TEST_STAMP)

# Plus only what the documentation site needs (MkDocs, Material, mkdocstrings): no PyTorch, Ray or ROS.
$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -c $(LOCK) -e '.[docs]'
	touch $(DOCS_STAMP)

# Resolve pyproject's ranges anew in a scratch environment and write the lock (then commit it,
# run `make test` and `dynabarn-bench --update-golden` if a version that decides results moved).
# PyTorch is taken as the CPU build that lies on this machine kind's disk: a bare range would
# pull a CUDA build of several GB.
lock:
	rm -rf .venv-lock && $(PY) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet --upgrade pip
	.venv-lock/bin/python -m pip install --quiet torch==2.13.0
	.venv-lock/bin/python -m pip install --quiet -e '.[$(EXTRAS)]'
	{ echo "# Exact versions for make install / make test (x86_64 Linux, CPython 3.11), from \`make lock\`."; \
	  echo "# pyproject.toml keeps the ranges; every result records the versions that decide it."; \
	  .venv-lock/bin/python -m pip freeze --all --exclude-editable | grep -v -E '^(dynabarn|pip)=='; } > $(LOCK).tmp
	mv $(LOCK).tmp $(LOCK)
	rm -rf .venv-lock

install: $(STAMP)

# Debian packages some tests and renderers need (installed by the project, never by hand);
# iproute2 for `ss`, which the tests use to see what listens where.
system-deps:
	@if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  need=""; for p in xvfb xdotool libosmesa6 libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri chromium fonts-dejavu-core iproute2; do \
	    dpkg -s $$p >/dev/null 2>&1 || need="$$need $$p"; done; \
	  if [ -n "$$need" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$need >/dev/null; fi; \
	fi
	$(MAKE) ros-deps

# ROS 1 (ros_comm 1.15, the Noetic generation) from Debian, for dynabarn-ros and its tests:
# built for Debian's /usr/bin/python3, which the bridge's ROS side runs on (root only).
ROS_PACKAGES := ros-core python3-rospy python3-sensor-msgs python3-nav-msgs python3-geometry-msgs \
	python3-tf2-msgs python3-move-base-msgs python3-actionlib python3-rosbag python3-std-msgs \
	python3-rosgraph-msgs python3-visualization-msgs python3-tf2-ros
ros-deps:
	@if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  need=""; for p in $(ROS_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || need="$$need $$p"; done; \
	  if [ -n "$$need" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$need >/dev/null; fi; \
	fi

# ROS 2 Jazzy's core (rclcpp, rclpy over Debian's Cyclone DDS, messages, tf2, launch,
# ros2cli, rosbag2) built from fetched sources with colcon into a prefix outside the package
# (DYNABARN_ROS2_WS, default ~/.cache/dynabarn/ros2): `make ros2-core ROS2_SRC=DIR`, DIR a
# folder of the repositories `python -m dynabarn.ros.ros2_build --repos` lists (vcstool:
# `vcs import DIR < FILE`). About 14 minutes on 2 cores; a second run builds nothing.
ros2-deps:
	@if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  need=""; for p in $$($(BIN)/python -c 'from dynabarn.ros.ros2_build import BUILD_DEPENDENCIES as d; print(*d)'); do \
	    dpkg -s $$p >/dev/null 2>&1 || need="$$need $$p"; done; \
	  if [ -n "$$need" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$need >/dev/null; fi; \
	else echo "ros2-deps: run as root to install Debian's build dependencies"; fi

ros2-core: $(STAMP) ros2-deps
	@[ -n "$(ROS2_SRC)" ] || { echo "ros2-core: give ROS2_SRC=<folder of the fetched repositories> (python -m dynabarn.ros.ros2_build --repos lists them)"; exit 2; }
	$(BIN)/python -m dynabarn.ros.ros2_build --source $(ROS2_SRC)

# Nav2 1.3.4 (controller server with DWB and MPPI, planner server with NavFn, costmap_2d,
# lifecycle manager, BT navigator) as an overlay on the ROS 2 core, from fetched sources
# (`python -m dynabarn.ros.nav2_build --repos` lists them): `make nav2 NAV2_SRC=DIR`, into
# DYNABARN_NAV2_WS (default ~/.cache/dynabarn/nav2). About 16 minutes on 2 cores.
nav2-deps: ros2-deps
	@if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  need=""; for p in $$($(BIN)/python -c 'from dynabarn.ros.nav2_build import BUILD_DEPENDENCIES as d; print(*d)'); do \
	    dpkg -s $$p >/dev/null 2>&1 || need="$$need $$p"; done; \
	  if [ -n "$$need" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$need >/dev/null; fi; \
	else echo "nav2-deps: run as root to install Debian's build dependencies"; fi

nav2: $(STAMP) nav2-deps
	@[ -n "$(NAV2_SRC)" ] || { echo "nav2: give NAV2_SRC=<folder of the fetched repositories> (python -m dynabarn.ros.nav2_build --repos lists them)"; exit 2; }
	$(BIN)/python -m dynabarn.ros.nav2_build --source $(NAV2_SRC)

# ROS 1's navigation stack (move_base) built from source against Debian's ROS 1, into a
# catkin workspace outside the package (DYNABARN_NAV_WS, default ~/.cache/dynabarn/ros_nav):
# `make ros-nav` (the dependencies need root; NAV_SRC=DIR builds a local checkout instead
# of fetching the pinned commit with git). About 6 minutes on 2 cores.
ros-nav-deps:
	@if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  need=""; for p in git $$($(BIN)/python -c 'from dynabarn.ros.nav_build import BUILD_DEPENDENCIES as d; print(*d)'); do \
	    dpkg -s $$p >/dev/null 2>&1 || need="$$need $$p"; done; \
	  if [ -n "$$need" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$need >/dev/null; fi; \
	else echo "ros-nav-deps: run as root to install Debian's build dependencies"; fi

ros-nav: $(STAMP) ros-deps ros-nav-deps
	$(BIN)/python -m dynabarn.ros.nav_build $(if $(NAV_SRC),--source $(NAV_SRC))

# teb_local_planner (with costmap_converter, move_base_flex's core and g2o) from source
# into the same workspace: `make ros-teb` after `make ros-nav` (TEB_SRC=DIR: a folder of
# local checkouts, see `python -m dynabarn.ros.teb_build --help`). About 20 minutes on 2 cores.
ros-teb-deps:
	@if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  need=""; for p in $$($(BIN)/python -c 'from dynabarn.ros.teb_build import BUILD_DEPENDENCIES as d; print(*d)'); do \
	    dpkg -s $$p >/dev/null 2>&1 || need="$$need $$p"; done; \
	  if [ -n "$$need" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$need >/dev/null; fi; \
	else echo "ros-teb-deps: run as root to install Debian's build dependencies"; fi

ros-teb: $(STAMP) ros-deps ros-nav-deps ros-teb-deps
	@$(BIN)/python -c 'import sys; from dynabarn.ros.nav_build import built, default_workspace; sys.exit(built(default_workspace()) is None)' \
	  || $(MAKE) ros-nav
	$(BIN)/python -m dynabarn.ros.teb_build $(if $(TEB_SRC),--sources $(TEB_SRC))

worlds: $(STAMP)
	$(BIN)/dynabarn-worlds generate
	$(BIN)/dynabarn-worlds generate --tier all

demo: $(STAMP)
	$(BIN)/dynabarn-run --world 137 --planner dwa

# The whole suite, a worker per core (about 21 minutes on 2 cores kept busy by other work); every test has a time
# limit (pyproject.toml). DYNABARN_REQUIRE_ALL=1 (CI) fails on a skip that lacks only an install.
test: $(TEST_STAMP)
	$(BIN)/python -m pytest -q -n auto

# The edit loop: all but the tests marked slow (under 2 minutes on 2 cores).
test-fast: $(TEST_STAMP)
	$(BIN)/python -m pytest -q -n auto -m "not slow"

# The documentation site into site/ (open site/index.html); strict: a broken link, anchor
# or API reference fails the build.
docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --clean

docs-serve: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs serve --dev-addr 127.0.0.1:8000

lint: $(TEST_STAMP)
	$(BIN)/ruff check . && $(BIN)/ruff format --check .

format: $(TEST_STAMP)
	$(BIN)/ruff format . && $(BIN)/ruff check --fix .

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py

# The README's result tables and figures, from the committed results/ (README "Comparison with the paper").
readme: $(STAMP)
	$(BIN)/python benchmarks/readme_results.py
	$(BIN)/python benchmarks/tracking_figure.py

# The golden set: the same episodes as the committed ones, or every field that differs.
verify-golden: $(TEST_STAMP)
	$(BIN)/dynabarn-bench --verify-golden

clean:
	rm -rf $(VENV) .venv-lock runs *.egg-info .golden_worlds site
