# Two commands do everything on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: venv test lint demo paper clean

venv: $(STAMP)

# The editable install finds physics_mapper.msg_adapters in msg_adapters/ through setuptools' finder, which
# always warns that a folder named like the package in the working directory may shadow it: that folder is
# the package itself, so this one informational warning is filtered (by its text) for that command.
$(STAMP): requirements.txt requirements-dev.txt requirements-ray.txt setup.py
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -r requirements-dev.txt
	PYTHONWARNINGS="ignore:Editable installation" $(BIN)/pip install --quiet --no-deps --no-build-isolation -e .
	touch $(STAMP)

lint: venv
	$(BIN)/ruff check physics_mapper msg_adapters test benchmarks .ci
	$(BIN)/ruff format --check physics_mapper msg_adapters test benchmarks .ci
	$(BIN)/mypy

# vision_msgs has no PyPI wheel: the tests build its Detection3DArray into the venv (test/vision_msgs/).
VISION_MSGS := $(VENV)/.vision_msgs
$(VISION_MSGS): $(STAMP) $(wildcard test/vision_msgs/*) $(wildcard test/vision_msgs/msg/*.msg)
	test/vision_msgs/build.sh $(VENV) build/vision_msgs
	touch $@

# tf2_msgs neither: the tests build its TFMessage (/tf, /tf_static) the same way (test/tf2_msgs/).
TF2_MSGS := $(VENV)/.tf2_msgs
$(TF2_MSGS): $(STAMP) test/vision_msgs/build.sh test/vision_msgs/pypi_wheel_targets.cmake $(wildcard test/tf2_msgs/*) $(wildcard test/tf2_msgs/msg/*.msg)
	test/vision_msgs/build.sh $(VENV) build/tf2_msgs test/tf2_msgs
	touch $@

# UTF-8 mode: the tests read and compare the UTF-8 text the package writes (reports, solve --tree),
# whatever the machine's locale (LC_ALL=C turns it on by itself; a Latin-1 locale does not).
test: venv lint $(VISION_MSGS) $(TF2_MSGS)
	PYTHONUTF8=1 $(BIN)/pytest

# Starts the node on the pyramid scene, replays the shipped pyramid bag into it, prints the error
# with and without physics and the node's last map and diagnostics (physics_mapper/commands/demo.py).
demo: venv
	$(BIN)/physics-mapper demo

# The paper's figures at full size (20 runs, 1000 particles) into reports/: PNG + markdown + JSON each.
paper: venv
	$(BIN)/physics-mapper experiment all -o reports

clean:
	rm -rf $(VENV) build install log .pytest_cache .mypy_cache .ruff_cache
