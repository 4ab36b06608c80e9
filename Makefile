# `make demo` and `make test` each set up .venv on a fresh machine (CPU torch + the project).
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.xnlos-installed

.PHONY: demo test test-slow fuzz bench dataset table2 figures clean

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e ".[test,dask]"
	@touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/xnlos demo --out demo-out --overwrite

# The layer contracts of pyproject.toml ([tool.importlinter]) first, then the tests, spread over
# the machine's cores by pytest-xdist (XDIST=0 runs them in one process).
XDIST ?= auto
test: $(STAMP)
	$(VENV)/bin/lint-imports --no-cache
	$(PY) -m pytest -q -n $(XDIST)

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
	rm -rf demo-out figures .pytest_cache .hypothesis
