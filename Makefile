# The two set-up commands of README.md. Both install into .venv from pinned versions (requirements.lock)
# and are idempotent: the install step reruns only when requirements.lock or pyproject.toml change.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
TSTAMP := $(VENV)/.installed-test
CORES  ?= 2
# one BLAS thread per process: the matrices are small (tens of columns), and threads only cost CPU time on a
# shared machine; the workflow's jobs run side by side instead (override by setting these variables)
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1

.PHONY: install report test archive lint bench derive docs clean

$(STAMP): requirements.lock pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r requirements.lock
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	touch $(STAMP)

# test-only dependencies (pypdf, ruff), pinned in requirements-test.lock
$(TSTAMP): $(STAMP) requirements-test.lock
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r requirements-test.lock
	touch $(TSTAMP)

install: $(STAMP)

# A run that was killed leaves a lock: removed first when no Snakemake process runs here (tools/unlock_if_idle.py);
# jobs it left half done rerun (the profile's rerun-incomplete).
report: $(STAMP)
	$(BIN)/python tools/unlock_if_idle.py
	$(BIN)/snakemake --cores $(CORES) --workflow-profile workflow/profiles/default
	@echo "report: paper/build/report.html and paper/build/report.pdf"

# results/archive/stiffcal-<commit>.tar.gz for reviewers; check it with .venv/bin/stiffcal verify-archive FILE
archive: $(STAMP)
	$(BIN)/python tools/unlock_if_idle.py
	$(BIN)/snakemake --cores $(CORES) --workflow-profile workflow/profiles/default archive

# the suite on $(CORES) processes (pytest-xdist), a file per process so that a module's fixtures (the small
# workflow run above all) are built once; `.venv/bin/python -m pytest` alone runs it in one process
test: $(TSTAMP)
	$(BIN)/python -m pytest -n $(CORES) --dist loadfile

# Snakemake's own lint of the workflow, and ruff (pinned in requirements-test.lock; rules and the documented
# exceptions in pyproject.toml) on the Python sources
lint: $(TSTAMP)
	$(BIN)/snakemake --lint
	$(BIN)/ruff check src tests benchmarks tools workflow/scripts examples

# the whole pipeline beside the commit before issue 16's cuts of its CPU (both run from scratch: about 3 minutes)
PIPELINE_BASELINE ?= 863eed4
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_plans.py
	$(BIN)/python benchmarks/bench_criteria.py
	$(BIN)/python benchmarks/bench_design_cache.py
	$(BIN)/python benchmarks/bench_maps.py
	$(BIN)/python benchmarks/bench_spatial.py
	$(BIN)/python benchmarks/bench_urdf.py
	$(BIN)/python benchmarks/bench_analysis.py
	$(BIN)/python benchmarks/bench_pipeline.py --baseline $(PIPELINE_BASELINE)

# Rewrite the docs' lists that are written from the registries (criteria, catalogue causes; tools/registry_docs.py);
# tests/test_docs.py fails when one is stale
docs: $(STAMP)
	$(BIN)/python tools/registry_docs.py

# Regenerate src/stiffcal/planning/_map_polynomials.py (committed) from its symbolic derivation; needs sympy.
derive: $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check sympy==1.14.0
	$(BIN)/python tools/derive_map_polynomials.py src/stiffcal/planning/_map_polynomials.py

clean:
	rm -rf results figures paper/build logs .snakemake .stiffcal
