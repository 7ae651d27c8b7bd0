# Two entry points for a fresh machine: `make demo` and `make test`. Both create .venv on first use.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
export AMENT_PREFIX_PATH := $(abspath $(VENV))

.PHONY: demo test lint typecheck unit kernels bench study experiments clean venv docs mrcal-venv mrcal-judge

venv: $(STAMP)

$(STAMP): requirements.txt setup.py setup.cfg package.xml $(wildcard tools/msg_packages/*/* tools/msg_packages/*/msg/*) tools/build_msg_package.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps -e .
	$(PY) tools/build_msg_package.py --venv $(VENV)  # tf2_msgs (no wheel on PyPI) from its definition, ~10-20 s
	$(PY) -m pascal_calib_ros.detect.edge_kernels  # compile the detection kernels once (numba caches them)
	$(PY) -m pascal_calib_ros.calibrate.solver.edge_row_kernels  # and the refinement's
	touch $(STAMP)

demo: $(STAMP)
	tools/in_netns $(PY) tools/demo.py

test: lint typecheck unit kernels

lint: $(STAMP)
	$(VENV)/bin/ruff check pascal_calib_ros test tools
	$(VENV)/bin/lint-imports --no-logo --no-cache

# the node tables of docs/nodes.md from the nodes' own tables (a test fails when the page is stale)
docs: $(STAMP)
	$(PY) -m pascal_calib_ros.ros.docs

typecheck: $(STAMP)
	$(VENV)/bin/mypy pascal_calib_ros

# mrcal as a judge (tools/mrcal_judge.py) in .venv-mrcal: Python 3.12/3.13 only (mrcal's wheels)
mrcal-venv:
	tools/mrcal_venv

# made for the tests when a Python 3.12/3.13 is there (about 15 s; a minute when pip downloads); without
# one, or offline, the tests that need mrcal skip and say why
mrcal-judge:
	@tools/mrcal_venv || echo "make: no mrcal judge (see above): the tests that need it skip"

unit: $(STAMP) mrcal-judge
	tools/in_netns $(PY) -m pytest -q test

# the numerical tests again under every OpenBLAS kernel this CPU runs (results must not hang on rounding)
kernels: $(STAMP)
	tools/test_kernels $(PY)

# detection and calibration speed, then the node's throughput across processes (5 MP at 10 Hz)
bench: $(STAMP)
	$(VENV)/bin/pascal-calib bench
	tools/in_netns $(PY) tools/bench_node.py

experiments: $(STAMP)
	for e in methods layouts literal board reconstruct; do $(VENV)/bin/pascal-calib experiment $$e --out docs/figures || exit 1; done

study: $(STAMP)
	$(VENV)/bin/pascal-calib study accuracy --out out/study
	$(VENV)/bin/pascal-calib study edge-bias --out out/study

clean:
	rm -rf $(VENV) .venv-mrcal build install log *.egg-info demo_out out
