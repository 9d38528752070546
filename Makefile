# Two commands for a newcomer: `make demo` (the pendulum skill, end to end) and `make test`.
# Both set everything up first: system packages, the virtualenv .venv, the Python packages at the
# versions of requirements.lock (`make lock` rewrites it from the installed environment).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
RUN_STAMP := $(VENV)/.installed-run
LOCK   := requirements.lock
export MUJOCO_GL ?= egl

.PHONY: demo test test-slow test-interop test-lerobot bench setup lock clean

# The demo needs the runtime dependencies only; the tests also their extras.
demo: $(RUN_STAMP)
	$(BIN)/multiform demo pendulum --out runs/pendulum

test: $(STAMP)
	$(BIN)/pytest -q

test-slow: $(STAMP)
	$(BIN)/pytest -q -m slow

# LeRobot and robomimic pin torch and torchvision releases of their own (torchvision's PyPI builds
# need the CUDA torch, which cannot sit beside the CPU torch of .venv): they get one environment of
# their own (about 8.5 GB, 5 GB of it the CUDA libraries of PyPI's torch; built in 3-10 minutes,
# without pip's cache so that the disk holds the wheels only once), used only to load multiform's
# exports with LeRobot's own LeRobotDataset and robomimic's own file_utils and SequenceDataset.
INTEROP_VENV := .venv-interop
$(INTEROP_VENV)/.installed:
	test -x $(INTEROP_VENV)/bin/python || $(PYTHON) -m venv $(INTEROP_VENV)
	$(INTEROP_VENV)/bin/python -m pip install -q --no-cache-dir 'lerobot==0.4.4' 'six>=1.16' 'h5py>=3.10' 'matplotlib>=3.8'
	$(INTEROP_VENV)/bin/python -m pip install -q --no-cache-dir --no-deps robomimic==0.3.0
	touch $@

test-interop: $(STAMP) $(INTEROP_VENV)/.installed
	MULTIFORM_INTEROP_PYTHON=$(INTEROP_VENV)/bin/python $(BIN)/pytest -q -m interop

test-lerobot: test-interop

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

setup: $(STAMP)

$(RUN_STAMP): pyproject.toml $(LOCK) scripts/system-deps.sh
	bash scripts/system-deps.sh
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e . -c $(LOCK)
	touch $@

$(STAMP): $(RUN_STAMP)
	$(BIN)/python -m pip install -q -e '.[test,teleop,lerobot,interop,view,ray,video,mentors]' -c $(LOCK)
	$(BIN)/python -m pip install -q --no-deps robomimic==0.3.0
	touch $@

# After changing a dependency in pyproject.toml: install it (`make setup`, or pip install without
# the lock), then write the versions now installed into the lock.
lock:
	$(BIN)/python scripts/lock.py > $(LOCK).new && mv $(LOCK).new $(LOCK)

clean:
	rm -rf $(VENV) $(INTEROP_VENV) runs .pytest_cache .hypothesis
