# Two commands do all set-up on a fresh machine:
#   make demo   — create .venv, install jaxtrack, run the main job
#   make test   — create .venv, install jaxtrack with test extras, run the tests
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test docs lint models bench bench-gplvm bench-gplvm-exact bench-tracking bench-gpy-env detector bench-peers-env install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q torch==2.13.0  # the local CPU wheel, before kornia (pyproject.toml)
	$(BIN)/pip install -q -e ".[dev,kornia]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/jaxtrack demo

test: $(STAMP)
	$(BIN)/python -m pytest

# the design pages and the API reference from the docstrings, into site/ (strict: warnings fail)
docs: $(STAMP)
	$(BIN)/mkdocs build --strict --site-dir site

lint: $(STAMP)
	$(BIN)/ruff check jaxtrack tests benchmarks

# retrain the models bundled in jaxtrack/data/files/models/ (latent, linear-combination,
# postures) from the training-subject clips bundled with the package, with their descriptions
models: $(STAMP)
	JAXTRACK_NO_SHARED=1 $(BIN)/python -m jaxtrack.data.models --rebuild

bench: $(STAMP)
	$(BIN)/python -m benchmarks.particle_counts

# GPy (the GPLVM benchmark's reference) lives in its own venv so it never touches jaxtrack's
bench-gpy-env:
	$(PYTHON) -m venv .venv-gpy && .venv-gpy/bin/pip install -q -r benchmarks/requirements-gpy.txt

# MediaPipe Pose, the detector jaxtrack runs (jaxtrack/vision/mediapipe.py), in its own venv,
# never in .venv: mediapipe 0.10.21 needs numpy < 2, jax numpy >= 2
detector: .venv-mediapipe/.installed

.venv-mediapipe/.installed: jaxtrack/vision/requirements-mediapipe.txt
	$(PYTHON) -m venv .venv-mediapipe
	.venv-mediapipe/bin/pip install -q -r jaxtrack/vision/requirements-mediapipe.txt
	.venv-mediapipe/bin/python jaxtrack/vision/_mediapipe_worker.py --check
	touch $@

# the particle-count benchmark's peer libraries, each in its own venv (particles needs numpy<2,
# cuthbert its own jax, pydpf torch): benchmarks/_peers.py runs them when these exist. pydpf 1.2
# declares Python >= 3.12 and torchvision/torchaudio, but imports neither and runs on 3.11: it is
# installed without its declared dependencies, beside the torch 2.13.0 CPU wheel and what it imports

bench-peers-env:
	$(PYTHON) -m venv .venv-peers-particles && .venv-peers-particles/bin/pip install -q particles==0.4 "numpy<2"
	$(PYTHON) -m venv .venv-peers-cuthbert && .venv-peers-cuthbert/bin/pip install -q cuthbert==0.1.1
	$(PYTHON) -m venv .venv-peers-pydpf && .venv-peers-pydpf/bin/pip install -q torch==2.13.0 && \
	  .venv-peers-pydpf/bin/pip install -q --no-deps --ignore-requires-python pydpf==1.2.3 && \
	  .venv-peers-pydpf/bin/pip install -q joblib numpy pandas polars

bench-gplvm: $(STAMP)
	$(BIN)/python -m benchmarks.gplvm

# the exact GPLVM (every pose active, L-BFGS) against GPy's exact GPLVM, both inverted by
# reconstruction as well as GPy by its own infer_newX (README, Benchmarks)
bench-gplvm-exact: $(STAMP)
	$(BIN)/python -m benchmarks.gplvm --sizes 1000 --active-size 1000 --iterations 1 \
		--active-steps 30 --optimiser lbfgs --inverse reconstruction --gpy-model full --subsets 3 \
		--gpy-max-iters 60

# tracking error and ms/frame of latent / CONDENSATION / MHT vs N (~15 minutes on 2 cores)
bench-tracking: $(STAMP)
	$(BIN)/python -m papers.tian2005.particle_sweep

clean:
	rm -rf $(VENV) build *.egg-info
