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
	$(VENV)/bin/workbench design fixtures/default/job.toml --out out/demo
	@echo "pictures: out/demo/print.png (the print), out/demo/views.png (which view owns what),"
	@echo "          out/demo/stretch.png (film stretch); 3D: out/demo/decorated.glb"

bench: install
	$(PY) benchmarks/bench_flatten.py $(if $(BIG),--big)
	$(PY) benchmarks/bench_design.py
	$(PY) benchmarks/bench_render.py
	$(PY) -m pytest -q -m slow

lint: install
	$(VENV)/bin/ruff check workbench tests benchmarks fixtures docs

clean:
	rm -rf $(VENV) out .pytest_cache
