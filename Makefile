# repertoire: every target does its own set-up on a fresh machine.
#   make demo   - install, then run `repertoire demo` (figures, graphs, HTML replays in out/demo)
#   make test   - install, then run the whole test suite
#   make bench  - install, then run every benchmark script and print its figures
#   make lint   - ruff check + format check

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip --disable-pip-version-check -q
IS_ROOT := $(shell [ "$$(id -u)" = "0" ] && echo yes)

.PHONY: demo test bench lint graphviz chromium clean

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip

# One stamp per extra set, redone when pyproject.toml changes.
$(VENV)/.stamp-run: pyproject.toml | $(VENV)/bin/python
	$(PIP) install -e ".[pddl]"  # the demo's refinement studies plan with PDDL
	touch $@

$(VENV)/.stamp-dev: pyproject.toml | $(VENV)/bin/python
	$(PIP) install -e ".[dev,dask,peers]"
	touch $@

graphviz:
	@if command -v dot >/dev/null 2>&1; then :; \
	elif [ "$(IS_ROOT)" = "yes" ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing graphviz (apt-get) for diagram images"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq graphviz >/dev/null) \
	    || echo "graphviz install failed: diagrams are written as .dot files only"; \
	else \
	  echo "note: graphviz 'dot' not found and not root; install it with 'sudo apt-get install graphviz'."; \
	  echo "      Going on: diagrams are written as .dot files without SVG/PNG images."; \
	fi

chromium:
	@if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then :; \
	elif [ "$(IS_ROOT)" = "yes" ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing chromium (apt-get) for the HTML replay test"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
	    || echo "chromium install failed: the replay browser test will be skipped"; \
	else \
	  echo "note: chromium not found and not root; the replay browser test will be skipped."; \
	fi

demo: $(VENV)/.stamp-run graphviz
	$(VENV)/bin/repertoire demo

test: $(VENV)/.stamp-dev graphviz chromium
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(PY) -m pytest -q -n 2 --dist loadfile

bench: $(VENV)/.stamp-dev
	@set -e; for f in tests/benchmarks/bench_*.py; do echo "== $$f"; $(PY) $$f; done

lint: $(VENV)/.stamp-dev
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

clean:
	rm -rf out .pytest_cache
