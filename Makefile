# cmlt — bootstrap, build, test, demo.
#
#   make demo   install what is missing, render sequences/cornell into renders/
#   make test   install what is missing, run ctest (C++) and pytest (Python)
#   make bench  run the benchmarks in tests/bench (not part of make test)
#
# Works as root on a fresh Debian 12 machine; elsewhere set SUDO=sudo or
# install the APT_PKGS yourself.

SHELL    := /bin/bash
PYTHON   ?= python3
VENV     ?= .venv
PY       := $(VENV)/bin/python
BUILD    := build/py
SUDO     ?=
APT_PKGS := build-essential cmake ninja-build libembree-dev libtbb-dev libosd-dev \
            googletest libgtest-dev python3-dev python3-venv
PY_PKGS  := scikit-build-core nanobind numpy usd-core openimageio "opencolorio>=2.2" \
            materialx rich matplotlib pytest
THREADS  ?= 2
DEMO_FRAMES ?= 1:24

.PHONY: all demo test ctest pytest bench install apt-deps clean

all: install

apt-deps:
	@missing=""; for p in $(APT_PKGS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "cmlt: installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$missing >/dev/null; \
	fi

$(VENV)/.deps-stamp: Makefile
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q $(PY_PKGS)
	@touch $@

# Editable install: Python sources are used in place; the C++ core, the
# nanobind module and the GoogleTest binary build incrementally in $(BUILD).
install: apt-deps $(VENV)/.deps-stamp
	$(PY) -m pip install -q --no-build-isolation -e . \
	  -C build-dir=$(BUILD) -C cmake.define.CMLT_BUILD_TESTS=ON

ctest: install
	ctest --test-dir $(BUILD) --no-tests=error --output-on-failure -j $(THREADS)

pytest: install
	$(PY) -m pytest -q

test: ctest pytest

demo: install
	$(VENV)/bin/cmlt render sequences/cornell/shot.usda --frames $(DEMO_FRAMES) \
	  --out renders/cornell/cornell.####.exr --threads $(THREADS) --preview
	$(VENV)/bin/cmlt contact-sheet 'renders/cornell/cornell.####.exr' \
	  --out renders/cornell/contact_sheet.png

bench: install
	$(PY) tests/bench/run_all.py

clean:
	rm -rf build renders
