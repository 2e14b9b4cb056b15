# DynaBARN on MuJoCo. `make demo` runs the main job, `make test` runs the tests.
# Both create the virtual environment in .venv when it is missing.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test

.PHONY: install demo worlds test lint format bench clean system-deps

# The package and what running it needs.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	touch $(STAMP)

# Plus the test tools and the optional extras the tests exercise (Ray, PyTorch CPU, Gymnasium).
$(TEST_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,ray,learn]'
	touch $(TEST_STAMP)

install: $(STAMP)

# Debian packages some tests and renderers need (installed by the project, never by hand).
system-deps:
	@if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  need=""; for p in xvfb xdotool libosmesa6 libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri; do \
	    dpkg -s $$p >/dev/null 2>&1 || need="$$need $$p"; done; \
	  if [ -n "$$need" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$need >/dev/null; fi; \
	fi

worlds: $(STAMP)
	$(BIN)/dynabarn-worlds generate

demo: $(STAMP)
	$(BIN)/dynabarn-run --world 137 --planner dwa

test: $(TEST_STAMP)
	$(BIN)/python -m pytest -q

lint: $(TEST_STAMP)
	$(BIN)/ruff check . && $(BIN)/ruff format --check .

format: $(TEST_STAMP)
	$(BIN)/ruff format . && $(BIN)/ruff check --fix .

bench: $(STAMP)
	$(BIN)/python -m dynabarn.benchmarks

clean:
	rm -rf $(VENV) runs *.egg-info
