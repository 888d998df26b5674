# Set-up and everyday commands; see README.md.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
DEV_STAMP := $(VENV)/.installed-dev

.PHONY: install dev test demo bench lint docs tutorial clean

# what the commands need (make demo, make tutorial); make dev adds the tests', the benchmarks' and
# the docs' tools (the second renderer, the peers, mkdocs): about half the download again
install: $(STAMP)

dev: $(DEV_STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	@# (--no-compile: Python compiles what a command imports when it first does, not every module
	@# of every package now; the install takes half the time)
	$(PY) -m pip install --quiet --no-compile -e .
	@# the command's script starts Python with Ctrl-C and SIGTERM held (workbench/launcher.py)
	$(PY) -m workbench.launcher $(VENV)/bin/workbench
	touch $(STAMP)

$(DEV_STAMP): $(STAMP)
	$(PY) -m pip install --quiet --no-compile -e '.[test,bench,docs]'
	@# (pip writes the script again)
	$(PY) -m workbench.launcher $(VENV)/bin/workbench
	touch $(DEV_STAMP)

# every core, a test file to each (tests/conftest.py starts the longest first)
test: dev
	$(PY) -m pytest -q -n auto --dist loadfile --no-loadscope-reorder

WB := $(VENV)/bin/workbench
DEMO := out/demo

# the whole pipeline on the bundled default job: design, print PDF, fixture PDF, two
# synthetic photos of three parts (one perfect, one with the film 0.8 mm off, one glossy with a bubble
# and an ink dropout), and each part's validation and QA report
# the photos from behind the part (azimuth 200°, elevation 45°, 330 mm): the fixture's colour chart, in
# front of the part, is then in the frame beyond it (from the front it sits between the camera and the
# part, out of the frame), and the part fills as much of it as from the front
demo: install
	@# each step as soon as what it needs is there, two at a time: each is one process, and a
	@# machine has two cores at least (each step's output printed together when it ends)
	$(MAKE) --no-print-directory -j2 --output-sync=target demo-all

.PHONY: demo-all demo-design demo-print demo-fixture demo-photo-perfect demo-photo-film demo-photo-defects \
	demo-part-perfect demo-part-film demo-part-defects

demo-all: demo-print demo-fixture demo-part-perfect demo-part-film demo-part-defects
	$(PY) fixtures/demo_summary.py $(DEMO)

demo-design:
	$(WB) design fixtures/default/job.toml --out $(DEMO)/design

demo-print: demo-design
	$(WB) pdf $(DEMO)/design -o $(DEMO)/print.pdf

demo-fixture:
	$(WB) board fixture fixtures/default/job.toml -o $(DEMO)/fixture.pdf

demo-photo-perfect: demo-design
	$(WB) render $(DEMO)/design --orbit 200,45,330 --size 4000x3000 --realistic -o $(DEMO)/photo_perfect.jpg

demo-photo-film: demo-design
	$(WB) render $(DEMO)/design --orbit 200,45,330 --size 4000x3000 --realistic --film-offset-mm 0.8,0 \
		-o $(DEMO)/photo_film_0.8mm.jpg

demo-photo-defects: demo-design
	$(WB) render $(DEMO)/design --orbit 200,45,330 --size 4000x3000 --realistic --gloss 0.5 \
		--defect bubble:45,30,6,1 --defect dropout:60,25,1.784 -o $(DEMO)/photo_defects.jpg

# three photos of three parts: one validation (and one QA report) per part, as a QA line runs them;
# each with the perfect photo's camera (PHOTO.json), as a lab's calibrated camera
demo-part-perfect: demo-photo-perfect
	$(WB) validate $(DEMO)/design $(DEMO)/photo_perfect.jpg --camera $(DEMO)/photo_perfect.json \
		--out $(DEMO)/validation/perfect

demo-part-film: demo-photo-film demo-photo-perfect
	$(WB) validate $(DEMO)/design $(DEMO)/photo_film_0.8mm.jpg --camera $(DEMO)/photo_perfect.json \
		--out $(DEMO)/validation/film_0.8mm

demo-part-defects: demo-photo-defects demo-photo-perfect
	$(WB) validate $(DEMO)/design $(DEMO)/photo_defects.jpg --camera $(DEMO)/photo_perfect.json \
		--out $(DEMO)/validation/defects

bench: dev
	$(PY) benchmarks/bench_flatten.py $(if $(BIG),--big)
	$(PY) benchmarks/bench_design.py
	$(PY) benchmarks/bench_render.py
	$(PY) benchmarks/bench_validate.py
	$(PY) benchmarks/bench_films.py
	$(PY) benchmarks/bench_defects.py
	$(PY) benchmarks/bench_suggest.py
	$(PY) benchmarks/bench_forming.py --rounds 2
	$(PY) benchmarks/bench_trend.py
	$(PY) benchmarks/bench_closed.py
	$(if $(SCANS),$(PY) benchmarks/films_on_scans.py --meshes $(SCANS) --within-share 0.99 0.98)
	$(if $(FACE),$(PY) benchmarks/bench_forming.py --job fixtures/face-mask-films/job.toml --scale 1.5 --min-fov-deg 0 --calibration-film --rounds 2)
	$(PY) -m pytest -q -m slow

lint: dev
	$(VENV)/bin/ruff check workbench tests benchmarks fixtures docs calib

# the documentation site (mkdocs.yml, docs/) into out/site; a broken link or anchor fails it, and
# so does a command or option the docs name that the commands do not have
docs: dev
	$(PY) -m mkdocs build --strict --site-dir out/site
	$(PY) docs/check_options.py

# every ```sh block of docs/tutorial.md, in order, in a fresh temporary folder (about a minute)
tutorial: install
	$(PY) docs/run_tutorial.py

clean:
	rm -rf $(VENV) out .pytest_cache
