# `make demo` and `make test` each set up .venv on a fresh machine from the committed lock
# (requirements.lock: exact versions of every dependency, CPU torch included), then the project
# itself without resolving anything again. `make lock` regenerates the lock from pyproject.toml's
# ranges; `make test-latest` runs the suite against the newest releases in a venv of its own.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.xnlos-installed
LOCK   := requirements.lock

.PHONY: demo test test-slow test-kernels test-latest lock fuzz docs bench benchmarks benchmarks-check dataset table2 figures clean

$(STAMP): pyproject.toml $(LOCK)
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet -r $(LOCK)
	$(PY) -m pip install --quiet --no-deps -e .
	@touch $(STAMP)

# The lock: pip-compile (pip-tools) over pyproject.toml's ranges with the test, dask and docs extras and
# the CPU build of torch (requirements-cpu.in); --upgrade takes the newest releases that fit.
lock:
	@test -x .venv-lock/bin/pip-compile || ($(PYTHON) -m venv .venv-lock && .venv-lock/bin/pip install --quiet pip-tools==7.6.2)
	.venv-lock/bin/pip-compile --quiet --upgrade --extra test --extra dask --extra docs --strip-extras --no-emit-index-url \
		--no-emit-find-links --output-file $(LOCK) pyproject.toml requirements-cpu.in

# The suite against the newest releases of every dependency (torch stays the pinned CPU build), so an
# upstream break is seen on purpose; the lock test is skipped there (XNLOS_UNLOCKED=1).
test-latest:
	@test -x .venv-latest/bin/python || $(PYTHON) -m venv .venv-latest
	.venv-latest/bin/python -m pip install --quiet --upgrade --upgrade-strategy eager -r requirements-cpu.in -e ".[test,dask,docs]"
	.venv-latest/bin/lint-imports --no-cache
	XNLOS_UNLOCKED=1 .venv-latest/bin/python -m pytest -q -n $(XDIST) -p no:cacheprovider

demo: $(STAMP)
	$(VENV)/bin/xnlos demo --out demo-out --overwrite

# The layer contracts of pyproject.toml ([tool.importlinter]) first, then the tests, spread over
# the machine's cores by pytest-xdist (XDIST=0 runs them in one process).
XDIST ?= auto
test: $(STAMP)
	$(VENV)/bin/lint-imports --no-cache
	$(PY) -m pytest -q -n $(XDIST)

# The numerically sensitive tests (marker `kernels`) under every OpenBLAS kernel of {Prescott, Nehalem,
# Haswell, SkylakeX} this processor can run × OPENBLAS_NUM_THREADS ∈ {1, 2} (tests/kernels/matrix.py;
# kernels the processor lacks are named as skipped). KERNEL_ARGS narrows the tests (CI runs a subset).
KERNEL_ARGS ?= -q -m kernels -p no:cacheprovider
test-kernels: $(STAMP)
	$(PY) tests/kernels/matrix.py $(KERNEL_ARGS)

# The documentation site (mkdocs.yml, docs/; the benchmark pages join it from benchmarks/) → site/
docs: $(STAMP)
	@test -x $(VENV)/bin/mkdocs || { echo "make docs: no mkdocs in $(VENV): rm $(STAMP) and run make docs again (the lock installs it)"; exit 1; }
	$(VENV)/bin/mkdocs build --strict --site-dir site

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

# The fuzz tests at full length (≥ 10,000 generated cases each; `make test` runs them briefly)
fuzz: $(STAMP)
	XNLOS_FUZZ=long $(PY) -m pytest -q -m fuzz

bench: $(STAMP)
	$(PY) benchmarks/pipeline_speed.py
	$(PY) benchmarks/forward_components.py
	$(PY) benchmarks/raytrace_speed.py
	$(MAKE) dataset
	$(PY) benchmarks/detectors.py
	$(PY) benchmarks/detector_errors.py --detectors swin_unet,unet,further_than_cfar,rtn --out benchmarks/detector_errors.md --figure benchmarks/detector_errors.png
	$(PY) benchmarks/residual_mirror.py

# The benchmark pages of benchmarks/pages.toml, each rerun by its seeded command (PAGES="a b" picks some);
# benchmarks-check compares their deterministic tables with a rerun and writes nothing
PAGES ?=
benchmarks: $(STAMP)
	$(PY) -m benchmarks.regenerate $(PAGES)

benchmarks-check: $(STAMP)
	$(PY) -m benchmarks.regenerate --check $(PAGES)

# The default simulated dataset (2,160 ray-traced maps, ≈ 2 min on 2 cores; resumes, no-op when complete)
dataset: $(STAMP)
	$(VENV)/bin/xnlos simulate configs/datasets/default.toml --out out/data/default --workers 2

# Table 2 of the paper: every row on the test split → out/eval/table2/eval.md (+ Fig. 6-style panels)
table2: dataset
	$(VENV)/bin/xnlos eval configs/ablations/table2.toml --out out/eval/table2

# Fig. 2 of the paper (path loss, specular ratio) and the antenna patterns, as PNG in figures/
figures: $(STAMP)
	$(PY) benchmarks/fig2.py --out figures
	$(PY) benchmarks/antenna_report.py --out figures
	$(PY) -m sims.raytrace.picture --out figures/raytrace_corner.png

clean:
	rm -rf demo-out figures site .pytest_cache .hypothesis
