# Set-up and everyday commands; see README.md.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install test demo bench lint clean

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $(STAMP)

test: install
	$(PY) -m pytest -q

demo: install
	$(VENV)/bin/workbench flatten fixtures/default/part.obj --out out/demo

bench: install
	$(PY) benchmarks/bench_flatten.py $(if $(BIG),--big)
	$(PY) -m pytest -q -m slow

lint: install
	$(VENV)/bin/ruff check workbench tests benchmarks fixtures

clean:
	rm -rf $(VENV) out .pytest_cache
