# Two commands for a newcomer: `make demo` (the pendulum skill, end to end) and `make test`.
# Both set everything up first: system packages, the virtualenv .venv, the Python packages.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
export MUJOCO_GL ?= egl

.PHONY: demo test test-slow bench setup clean

demo: $(STAMP)
	$(BIN)/multiform demo pendulum --out runs/pendulum

test: $(STAMP)
	$(BIN)/pytest -q

test-slow: $(STAMP)
	$(BIN)/pytest -q -m slow

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

setup: $(STAMP)

$(STAMP): pyproject.toml scripts/system-deps.sh
	bash scripts/system-deps.sh
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test,ray]'
	touch $(STAMP)

clean:
	rm -rf $(VENV) runs .pytest_cache .hypothesis
