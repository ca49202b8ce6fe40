# exobench quick start:  make run   (install everything, run every track's quick suite)
#                        make test  (install everything, run the tests)
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
STAMP := $(VENV)/.installed
export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= $(MUJOCO_GL)

# Editable install in setuptools' strict mode: every module linked under build/ with a .pth to
# that tree, which static analysers and editors follow (the default mode installs an import hook
# they cannot see). A module added or removed needs new links: the install depends on the list
# of modules, rewritten only when it changes.
EDITABLE := --config-settings editable_mode=strict
MODULES := $(VENV)/.modules
$(shell mkdir -p $(VENV) && find core models envs perception mapping benchmarks -name '*.py' -not -path '*/__pycache__/*' \
	| LC_ALL=C sort > $(MODULES).new && { cmp -s $(MODULES).new $(MODULES) || mv $(MODULES).new $(MODULES); }; rm -f $(MODULES).new)

SYSTEM_LIBS := libusb-1.0.so.0 libEGL.so.1 libOSMesa.so libGL.so.1
DEBIAN_PKGS := libusb-1.0-0 libegl1 libosmesa6 libgl1 libgomp1

.PHONY: run test bench lint system clean
# every track's episodes in one pool on every core (benchmarks/run_tracks.py): the same records
# as one at a time (runner.py: episode seeds do not depend on the jobs or the order)
JOBS ?= $(shell nproc 2>/dev/null || echo 1)
run: $(STAMP)
	$(VENV)/bin/exobench run --jobs $(JOBS)

test: $(STAMP)
	$(VENV)/bin/python -m pytest

bench: $(STAMP)
	$(VENV)/bin/python -m pip install -q -e '.[test,ray,bench,orbslam3]' $(EDITABLE)
	$(VENV)/bin/exobench bench rtls
	$(VENV)/bin/exobench bench sim
	$(VENV)/bin/exobench bench lidar
	$(VENV)/bin/exobench bench locomotion

lint: $(STAMP)
	$(VENV)/bin/ruff check .

# Debian libraries that open3d and MuJoCo's off-screen renderer load at run time.
system:
	@missing=""; for lib in $(SYSTEM_LIBS); do ldconfig -p | grep -q "$$lib" || missing="$$missing $$lib"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing system libraries:$$missing"; \
	    DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(DEBIAN_PKGS) >/dev/null; \
	  else \
	    echo "missing system libraries:$$missing; run: sudo apt-get install -y $(DEBIAN_PKGS)"; exit 1; \
	  fi; \
	fi

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install -q --upgrade pip

$(STAMP): pyproject.toml $(MODULES) | $(VENV)/bin/python system
	$(VENV)/bin/python -m pip install -q -e '.[test,ray,orbslam3]' $(EDITABLE)
	@touch $(STAMP)

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info
