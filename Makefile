# geoproc: `make demo` and `make test` do all set-up on a fresh machine.
# Every target is safe under `make -j`.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
GEO    := $(VENV)/bin/geoproc
STAMP  := $(VENV)/.setup-stamp
FIXTURES := fixtures/data/.stamp
DEMO   := out/demo
PYTEST_ARGS ?=

.PHONY: setup fixtures test test-all demo demo-info demo-summary bench lint clean

setup: $(STAMP)

# Redone only when the package metadata changes.
$(STAMP): pyproject.toml setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $@

fixtures: $(FIXTURES)

$(FIXTURES): fixtures/make_fixtures.py $(STAMP)
	$(PY) fixtures/make_fixtures.py fixtures/data > /dev/null
	touch $@

test: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_ARGS)

test-all: $(STAMP)
	$(PY) -m pytest -q -m "" $(PYTEST_ARGS)

# ---- demo: every subcommand on the project's own fixtures, into out/demo ----
demo: demo-summary

$(DEMO)/.dir:
	mkdir -p $(DEMO)
	touch $@

demo-info: $(FIXTURES) $(DEMO)/.dir
	$(GEO) info fixtures/data/torus.ply --quiet --report $(DEMO)/info_torus.json --check 'genus==1' > $(DEMO)/info_torus.txt
	$(GEO) info fixtures/data/grid.ply --quiet --json --report $(DEMO)/info_grid.json --check 'boundary_loops==1' > $(DEMO)/info_grid.txt

DEMO_STEPS := demo-info

demo-summary: $(DEMO_STEPS)
	$(PY) -m geoproc_cli.report_table $(DEMO)

# ---- benchmarks against peer libraries (never part of `make test`) ----
bench: $(STAMP)
	$(PY) -m pip install --quiet -e ".[test,bench]"
	@for script in bench/*.py; do echo "== $$script"; $(PY) $$script || exit 1; done

lint: $(STAMP)
	$(PY) -m ruff check geoproc cli tests fixtures bench

clean:
	rm -rf out fixtures/data .pytest_cache .ruff_cache .benchmarks build *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
