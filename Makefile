# radar2shape: every target that needs the environment depends on `install`, which is a no-op
# when .venv is up to date with pyproject.toml. `make help` lists the targets.
SHELL := /bin/bash
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
export WANDB_SILENT := true

CONFIG ?= conf/trainer/cpu.yaml conf/experiment/toy_sphere.yaml  # layered: each file becomes a --config
GRID ?= table1
DATA_CONFIG ?= conf/data/parts.yaml
DATA_DIR ?= data/parts
WORKERS ?= 2

.DEFAULT_GOAL := help
.PHONY: help install test test-full demo data data-real data-real-variants fit test-model sweep report results monocone default-model real-model validation bench clean

help: ## List the targets
	@grep -E '^[a-zA-Z_-]+:.*## ' $(MAKEFILE_LIST) | awk 'BEGIN {FS = ":.*## "}; {printf "  %-12s %s\n", $$1, $$2}'

$(STAMP): pyproject.toml
	@test -x "$(PY)" || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e ".[dev]"
	@touch $(STAMP)

install: $(STAMP) ## Create .venv with torch (CPU) and the project in editable mode

test: install ## Run the default test suite (not slow)
	WANDB_MODE=disabled $(PY) -m pytest -m "not slow" -q

test-full: install ## Run every test, slow ones included
	WANDB_MODE=disabled $(PY) -m pytest -q

demo: install ## Build a tiny dataset, train and test the default models on CPU, write reports/demo/ (conf/grid/demo.yaml)
	$(VENV)/bin/radar2shape sweep demo
	$(VENV)/bin/radar2shape report --grid demo

data: install ## Build the default dataset (DATA_CONFIG=, DATA_DIR=, WORKERS=)
	$(VENV)/bin/radar2shape build-data --config $(DATA_CONFIG) --out $(DATA_DIR) --workers $(WORKERS)

REAL_SRC ?= data/real-src
data-real: install ## Build the real-target dataset (FlightGear + Gazebo, conf/data/real.yaml) into data/real; fetches the FlightGear packages into data/real-src/ once (WORKERS=)
	@if [ ! -d $(REAL_SRC)/usr/share/games/flightgear/AI ]; then \
	  set -e; rm -rf $(REAL_SRC).partial; mkdir -p $(REAL_SRC).partial/debs; \
	  (cd $(REAL_SRC).partial/debs && apt-get download flightgear-data-ai flightgear-data-models); \
	  for deb in $(REAL_SRC).partial/debs/*.deb; do dpkg-deb -x "$$deb" $(REAL_SRC).partial; done; \
	  rm -rf $(REAL_SRC).partial/debs $(REAL_SRC); mv $(REAL_SRC).partial $(REAL_SRC); fi
	$(VENV)/bin/radar2shape build-data --config conf/data/real.yaml --out data/real --workers $(WORKERS)

data-real-variants: data-real ## data/real plus a stretched copy of every training object (conf/data/real_variants.yaml) into data/real-variants
	@# The originals' records are a pure function of their task, which the variants leave unchanged
	@# (tests/data/test_real_sources.py): link them in, so that the build only makes the variants.
	@if [ ! -d data/real-variants/records ]; then mkdir -p data/real-variants && cp -al data/real/records data/real-variants/records; fi
	$(VENV)/bin/radar2shape build-data --config conf/data/real_variants.yaml --out data/real-variants --workers $(WORKERS)

fit: install ## Train: make fit CONFIG="conf/trainer/cpu.yaml conf/callbacks/shape_metrics.yaml conf/experiment/NAME.yaml"
	$(VENV)/bin/radar2shape fit $(foreach c,$(CONFIG),--config $(c))

test-model: install ## Test a model: make test-model CONFIG=... CKPT=path/to.ckpt
	$(VENV)/bin/radar2shape test $(foreach c,$(CONFIG),--config $(c)) $(if $(CKPT),--ckpt_path $(CKPT))

sweep: install ## Run a config grid and write its report: make sweep GRID=table1 (conf/grid/GRID.yaml)
	$(VENV)/bin/radar2shape sweep $(GRID)

report: install ## Collect finished runs into the grid's report layout: make report GRID=table1 (rollsym: Table 2)
	$(VENV)/bin/radar2shape report --grid $(GRID)

monocone: install ## Zero-shot monocone experiment on simulated measurements -> reports/monocone/ (needs runs/rollsym and a Radar2Shape Stage 2)
	$(PY) scripts/monocone_experiment.py --table1-dir runs/table1
	$(VENV)/bin/radar2shape report --grid monocone

default-model: install ## Export Radar2Shape of table1-medium-stage2 (full, seed 2) as the model reconstruct uses without --ckpt
	$(PY) scripts/export_default_model.py --ckpt runs/table1-medium-stage2/radar2shape_long-full-seed2/fit/version_0/checkpoints/last.ckpt

real-model: install ## Export Radar2Shape of table1-real-long (circular, seed 0) as the model reconstruct --model real uses
	$(PY) scripts/export_default_model.py --ckpt runs/table1-real-long/radar2shape_circ_steps12k_stage2-seed0/fit/version_0/checkpoints/last.ckpt --out src/radar2shape/weights/radar2shape_real.ckpt

validation: install ## PO and PO + edge currents against the Austin RCS suite in ../shared/validation -> reports/radar/validation.md
	$(PY) -m radar2shape.radar.validation --out reports/radar/validation.md

results: install ## Rewrite docs/results.md, the model card and README's results table from reports/
	$(PY) -m radar2shape.reporting.results

bench: install ## Run the speed benchmarks under bench/
	@for b in bench/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean: ## Remove the environment, runs, built data and reports
	rm -rf $(VENV) runs data reports/demo wandb lightning_logs .pytest_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +

