# cmlt — bootstrap, build, test, demo.
#
#   make demo   install what is missing, render sequences/cornell into renders/
#   make test   install what is missing, run ctest (C++) and pytest (Python)
#   make bench  run the benchmarks in tests/bench (not part of make test)
#   make gallery  build the gallery's assets and render docs/gallery/ (not part of make test)
#   make schema rewrite plugins/usd/cmltSchemas from the settings table
#   make test-sanitize  ASan + UBSan build of the core and C++ tests in build/sanitize:
#               ctest, then a few Python renders with the sanitized module
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
            linux-perf valgrind \
            googletest libgtest-dev python3-dev python3-venv
# pyproject.toml's [build-system] requires: the editable install builds without
# isolation (incremental C++ builds in $(BUILD)), so they must be in the venv. The
# package's own dependencies and its test extra come from pyproject.toml itself.
BUILD_REQS := "scikit-build-core>=0.10" "nanobind>=2.0"
THREADS  ?= 2
DEMO_FRAMES ?= 1:24

SAN_BUILD := build/sanitize
# leaks: on for the C++ suite; off in Python, which keeps its memory until exit
SAN_UBSAN := UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
SAN_ASAN  := ASAN_OPTIONS=abort_on_error=1:detect_stack_use_after_return=1

.PHONY: all demo test ctest pytest bench gallery install apt-deps schema clean test-sanitize

all: install

apt-deps:
	@missing=""; for p in $(APT_PKGS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "cmlt: installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$missing >/dev/null; \
	fi

$(VENV)/.deps-stamp: Makefile pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q $(BUILD_REQS)
	@touch $@

# Editable install with the test extra (pytest, matplotlib): Python sources are used
# in place; the C++ core, the nanobind module and the GoogleTest binary build
# incrementally in $(BUILD). The sources' bytecode is written once here: where
# PYTHONDONTWRITEBYTECODE is set (as on this project's machines) Python never caches
# it itself and every `cmlt` process would compile the package again (0.12 s).
install: apt-deps $(VENV)/.deps-stamp
	$(PY) -m pip install -q --no-build-isolation -e '.[test]' \
	  -C build-dir=$(BUILD) -C cmake.define.CMLT_BUILD_TESTS=ON
	$(PY) -m compileall -q src/cmlt

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

test-sanitize: install
	cmake -S . -B $(SAN_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMLT_SANITIZE=ON \
	  -DCMLT_BUILD_TESTS=ON -DPython_EXECUTABLE=$(abspath $(PY)) \
	  -Dnanobind_ROOT="$$($(PY) -m nanobind --cmake_dir)" >/dev/null
	cmake --build $(SAN_BUILD) -j $(THREADS)
	$(SAN_ASAN) $(SAN_UBSAN) ctest --test-dir $(SAN_BUILD) --no-tests=error --output-on-failure -j $(THREADS)
	LD_PRELOAD="$$($(CXX) -print-file-name=libasan.so) $$($(CXX) -print-file-name=libstdc++.so)" \
	  $(SAN_ASAN):detect_leaks=0 $(SAN_UBSAN) \
	  $(PY) tests/sanitize/renders.py $(SAN_BUILD)

bench: install
	$(PY) tests/bench/run_all.py

# assets written by docs/gallery/build_gallery.py (nothing downloaded), rendered small
gallery: install
	$(PY) docs/gallery/build_gallery.py --threads $(THREADS)

# rewrite the USD schema files from the settings table (after editing
# src/core/integrators/common/render_settings.h; make test fails while they are stale)
schema: install
	$(PY) -m cmlt.settings.usd_schema --write

clean:
	rm -rf build renders
