# Quick start: `make demo` and `make test`. Both create .venv on demand.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache
export NUMBA_THREADING_LAYER ?= omp
export MPLBACKEND ?= Agg

.PHONY: demo test test-mpi bench venv clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q --no-compile -e '.[test]'
	touch $@

demo: $(STAMP)
	$(BIN)/hmm demo --overwrite

test: $(STAMP)
	$(BIN)/python -m pytest -q tests --ignore=tests/mpi
	$(BIN)/python -m pytest -q --doctest-modules dem hmm
	$(MAKE) test-mpi

test-mpi: $(STAMP)
	NUMBA_NUM_THREADS=1 $(BIN)/mpiexec -n 2 $(BIN)/python -m mpi4py -m pytest -q -p no:cacheprovider tests/mpi

bench: $(STAMP)
	$(BIN)/python benchmarks/dem_throughput.py
	$(BIN)/python benchmarks/dt_speed_accuracy.py
	$(BIN)/python benchmarks/neighbor_backends.py
	$(BIN)/python benchmarks/step_profile.py
	$(BIN)/python benchmarks/contact_speed_accuracy.py
	$(BIN)/python benchmarks/shape_throughput.py
	$(BIN)/python benchmarks/rve_call.py
	$(BIN)/python benchmarks/mpi_scaling.py
	$(BIN)/python benchmarks/rve_vs_yade.py
	$(BIN)/python benchmarks/hmm_vs_femxdem.py
	$(BIN)/python benchmarks/pd_lammps.py
	$(BIN)/python benchmarks/pd_kirsch.py
	$(BIN)/python benchmarks/pd_surface_effect.py
	$(BIN)/python benchmarks/stability_map.py

clean:
	rm -rf $(VENV) .numba_cache .pytest_cache output
