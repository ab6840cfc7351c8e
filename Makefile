# Two commands do everything on a fresh machine:
#   make demo   -> creates .venv, installs the package, runs the main demo (outputs in runs/demo)
#   make test   -> creates .venv, installs the package with test extras, runs the default test suite
#                  (which builds the API reference with warnings as errors: tests/test_api_reference.py)
# Both install `.[dev]` (every extra) at the exact versions of constraints.txt.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= egl

.PHONY: install demo test test-slow test-hostile lint bench api clean

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip setuptools wheel
	# torch is named in the same command, pinned by constraints.txt to the release of the local CPU
	# build, so pip takes that build, never a CUDA one.
	$(BIN)/python -m pip install -c constraints.txt torch -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/ndp demo --out runs/demo

test: $(STAMP)
	$(BIN)/ruff check setup.py src tests benchmarks docs/api
	$(BIN)/ruff format --check setup.py src tests benchmarks docs/api
	$(BIN)/mypy
	# 2 pytest-xdist workers (the CI machine has 2 cores), one torch thread each
	# (tests/conftest.py); --dist loadfile: a test file runs on one worker, so a module-scope
	# fixture (a training, the API reference build) runs once
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

# the hostile-user catalogue alone, with its count per outcome printed (also in `make test`)
test-hostile: $(STAMP)
	$(BIN)/python -m pytest -q -s -m hostile tests/test_hostile.py

lint: $(STAMP)
	$(BIN)/ruff check setup.py src tests benchmarks docs/api
	$(BIN)/ruff format --check setup.py src tests benchmarks docs/api
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/python benchmarks/dmp_speed.py

# the API reference from the docstrings, browsable: open build/api/index.html (warnings are errors)
# The reference documents every module, the optional ones too (ndp.sb3 imports
# Stable-Baselines3, ndp.rl gymnasium), so it builds in the full development install (.venv,
# every extra and pdoc), as `make test` does.
api: $(STAMP)
	$(BIN)/python docs/api/build.py --out build/api

clean:
	rm -rf $(VENV) runs build/api
