# tensegrity_ros: `make run` and `make test` set up .venv from the pinned
# requirements on first use, then run. DDS stays on loopback everywhere.
SHELL := /bin/bash
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
CONFIG ?= config/default.yaml
PYTEST_ARGS ?=

export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
# One DDS domain per make invocation unless the caller chose one.
ROS_DOMAIN_ID ?= $(shell $(PYTHON) -c 'import os; print(1 + os.getpid() % 100)')
export ROS_DOMAIN_ID
export PYTHONUNBUFFERED := 1

.PHONY: setup run test test-numerics bench figures clean

setup: $(STAMP)

$(STAMP): requirements.txt setup.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	touch $(STAMP)

# Ctrl-C: on a terminal the recipe shell runs the node as a job of its own (set -m), so the
# terminal's SIGINT reaches the node only; the node shuts down and exits 0, and make returns
# the node's status rather than dying of the signal itself (130). `; exit $$?` keeps bash
# from exec'ing the node in place of the job-control shell.
run: $(STAMP)
	@echo "tensegrity_node on $(CONFIG), ROS_DOMAIN_ID=$(ROS_DOMAIN_ID), discovery LOCALHOST"
	if [ -t 0 ]; then set -m; fi; $(PY) -m tensegrity_ros.ros.node --ros-args --params-file $(CONFIG); exit $$?

# The suite on PYTEST_WORKERS pytest-xdist workers (each its own DDS domain: base + index,
# test/conftest.py), one BLAS thread each (the matrices are small; two workers fill the
# two cores).  `make test PYTEST_WORKERS=0` runs it in one process.  FULL_NECKS=1 adds the
# long sweeps (test_reference_tracking.py's whole nearly symmetric neck grid).
PYTEST_WORKERS ?= 2
XDIST = $(if $(filter 0,$(PYTEST_WORKERS)),,-n $(PYTEST_WORKERS) --dist loadgroup)
TEST_ENV = ROS_PYTHON_CHECK_FIELDS=1 OPENBLAS_NUM_THREADS=1
test: $(STAMP)
	$(TEST_ENV) $(PY) -m pytest $(XDIST) $(PYTEST_ARGS)

# The numerically sensitive tests (marker `numerics`: perfect bifurcations, flat crossings,
# mirror images, the reference's flows, counting clocks) on other machines' arithmetic:
# OpenBLAS's kernels for AVX2 (Haswell), AVX (Sandybridge), SSE4.2 (Nehalem) and, where
# this CPU has AVX-512, SkylakeX; numpy's own SIMD loops limited to the same class of
# machine (NPY_DISABLE_CPU_FEATURES).  Each config: <OPENBLAS_CORETYPE>:<numpy features
# off, comma-separated, or ->.  All must pass; the summary names the configs that failed.
# (x86-64 with AVX2 runs the first four; elsewhere only this machine's own arithmetic.)
# A config whose arithmetic is this machine's own (OpenBLAS picks that core here and the
# features it turns off are absent: tools/same_arithmetic.py) repeats what `make test` ran
# and is skipped, with a line saying so (only when the caller set neither variable, so that
# make test did run on this machine's own arithmetic); NUMERICS_REPEATS=1 runs it anyway.
NUMPY_AVX2 := X86_V4,AVX512_ICL,AVX512_SPR
NUMPY_SSE := X86_V3,$(NUMPY_AVX2)
ifeq ($(shell uname -m),x86_64)
NUMERICS_CONFIGS ?= Haswell:- Haswell:$(NUMPY_AVX2) Sandybridge:$(NUMPY_SSE) Nehalem:$(NUMPY_SSE) \
	$(if $(shell grep -qw avx512f /proc/cpuinfo 2>/dev/null && echo y),SkylakeX:-)
else
NUMERICS_CONFIGS ?= $(OPENBLAS_CORETYPE):-
endif
test-numerics: $(STAMP)
	@failed=; ran=; for config in $(NUMERICS_CONFIGS); do \
	  core=$${config%%:*}; off=$${config#*:}; [ "$$off" = - ] && off=; \
	  if [ -z "$(NUMERICS_REPEATS)$${OPENBLAS_CORETYPE}$${NPY_DISABLE_CPU_FEATURES}" ] && env -u OPENBLAS_CORETYPE -u NPY_DISABLE_CPU_FEATURES \
	      $(PY) tools/same_arithmetic.py $$core $${off:--}; then \
	    echo "== test-numerics: $$config skipped: this machine's own arithmetic, which make test ran"; \
	    continue; fi; \
	  echo "== test-numerics: OPENBLAS_CORETYPE=$$core NPY_DISABLE_CPU_FEATURES=$$off"; \
	  $(TEST_ENV) OPENBLAS_CORETYPE=$$core NPY_DISABLE_CPU_FEATURES=$$off \
	    $(PY) -m pytest $(XDIST) -m numerics -p no:cacheprovider $(PYTEST_ARGS) \
	    || failed="$$failed $$config"; ran="$$ran $$config"; \
	done; \
	if [ -n "$$failed" ]; then echo "test-numerics FAILED under:$$failed"; exit 1; fi; \
	echo "test-numerics: all configs passed:$$ran"

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(PY) $$b || exit 1; done

# The paper's figures (maps: figs. 3, 4a, 4b, 5 slices, 7 and the tip C of fig. 6, each with its
# exact boundary curves; diagrams: figs. 8a, 8b) from the CLI.
FIGDIR ?= docs/figures
TENSEGRITY := $(VENV)/bin/tensegrity
figures: $(STAMP)
	mkdir -p $(FIGDIR)
	$(TENSEGRITY) map --x rho 0.005 4 400 --y L2 0.005 4 400 --boundaries --png $(FIGDIR)/fig3_unloaded_rho_L2.png \
	  --title 'Fig. 3: unloaded (F3 = F4 = 0), L1 = 1, k = 100'
	$(TENSEGRITY) map --x rho 0.004 2 400 --y F -10 0 320 --L2 1 --boundaries --png $(FIGDIR)/fig4a_symmetric_pushing.png \
	  --title 'Fig. 4a: symmetric, pushing F = F3 = F4 <= 0, L1 = L2 = 1, k = 100'
	$(TENSEGRITY) map --x rho 0.004 2 400 --y F 0 10 320 --L2 1 --boundaries --png $(FIGDIR)/fig4b_symmetric_pulling.png \
	  --title 'Fig. 4b: symmetric, pulling F = F3 = F4 >= 0, L1 = L2 = 1, k = 100'
	$(TENSEGRITY) map --x rho 0.004 2 400 --y F4 0 10 320 --F3 5 --L2 1.5 --boundaries --png $(FIGDIR)/fig5a_slice_F3_5_L2_1.5.png \
	  --title 'Fig. 5a slice: F3 = 5, L2 = 3/2, L1 = 1, k = 100'
	$(TENSEGRITY) map --x rho 0.004 2 400 --y F4 0 10 320 --F3 5 --L2 1 --boundaries --png $(FIGDIR)/fig5b_slice_F3_5_L2_1.png \
	  --title 'Fig. 5b slice: F3 = 5, L2 = 1, L1 = 1, k = 100'
	$(TENSEGRITY) map --x rho 0.004 2 400 --y F4 0 10 320 --F3 5 --L2 0.5 --boundaries --png $(FIGDIR)/fig5c_slice_F3_5_L2_0.5.png \
	  --title 'Fig. 5c slice: F3 = 5, L2 = 1/2, L1 = 1, k = 100'
	$(TENSEGRITY) map --x rho 0.005 2 400 --y L2 0.005 2 400 --F -10 --boundaries --png $(FIGDIR)/fig7_pushing_rho_L2.png \
	  --title 'Fig. 7: F3 = F4 = -10 (pushing), L1 = 1, k = 100'
	$(TENSEGRITY) map --x rho 0.2 0.5 400 --y F 40 75 320 --L2 1 --boundaries --png $(FIGDIR)/fig6_tip_C_boundaries.png \
	  --title 'Tip of the 2-stable region (fig. 6, point C): F3 = F4, L1 = L2 = 1, k = 100'
	$(TENSEGRITY) diagram --from-rho 0.005 --to-rho 2 --count 400 --F 5 --L2 1 \
	  --track 0.5 0.1 0.5 --theta1 -1 --theta2 -1 --png $(FIGDIR)/fig8a_diagram.png \
	  --title 'Fig. 8a: L1 = L2 = 1, F3 = F4 = 5; path 0.5 -> 0.1 -> 0.5 from the lower branch (C1)'
	$(TENSEGRITY) diagram --from-rho 0.005 --to-rho 2 --count 400 --F 5 --L2 1 \
	  --track 0.5 1.2 0.5 --theta1 -1 --theta2 -1 --png $(FIGDIR)/fig8a_hysteresis_C2.png \
	  --title 'Fig. 8a: L1 = L2 = 1, F3 = F4 = 5; path 0.5 -> 1.2 -> 0.5 from the lower branch (C2)'
	$(TENSEGRITY) diagram --from-rho 0.005 --to-rho 2 --count 400 --F 5 --L2 1.05 \
	  --track 0.5 0.1 0.5 --theta1 -1 --theta2 -1 --png $(FIGDIR)/fig8b_diagram.png \
	  --title 'Fig. 8b: L1 = 1, L2 = 1.05, F3 = F4 = 5; path 0.5 -> 0.1 -> 0.5 (C1 is now a fold)'

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .hypothesis
