# Quick start: `make demo` and `make test`. Both create .venv on demand.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache
export NUMBA_THREADING_LAYER ?= omp
export MPLBACKEND ?= Agg

.PHONY: demo lint test test-shapes test-rest test-mpi docs-walk bench venv clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q --no-compile -e '.[test]'
	touch $@

demo: $(STAMP)
	$(BIN)/hmm demo --overwrite

# The suite runs as two pytest processes side by side, split where the compiled loops
# differ (level-set shapes and their contact solvers, mesh walls and rolling resistance /
# everything else), so that numba compiles the two halves at once (each cold time loop in
# a child process of its own, dem._jit.prepare); then the MPI tests. Both halves share
# one numba cache: the shapes' half skips the warm-up of the sphere loops
# (DEM_TEST_WARM=0, tests/conftest.py) and starts with the contact solvers, which need
# none, while the other half's warm-up compiles them. Tests that run the same loop go to
# the same half where they can (the Hertz sphere on a plane, mesh or not), so that it is
# compiled once and not twice at the same moment.
SHAPE_FIRST := tests/dem/test_detection_admm.py tests/dem/test_detection_exact.py
SHAPE_TESTS := $(SHAPE_FIRST) $(filter-out $(SHAPE_FIRST), \
	$(sort $(wildcard tests/dem/test_detection_*.py tests/dem/test_shape*.py \
	tests/dem/test_io_shapes.py tests/dem/test_interpreted.py tests/dem/test_compound.py \
	tests/dem/test_meshwall*.py tests/dem/test_scene_meshes.py \
	tests/dem/test_rolling_resistance.py tests/dem/test_chung_ooi.py \
	tests/dem/test_hopper_beverloo.py tests/test_angle_of_repose.py)))
# the documentation pages run as written (about 4 minutes), shared between the halves
DOC_TESTS := tests/test_doc_pages.py
DOC_REST := batch or multiscale
PYTEST := $(BIN)/python -m pytest -q -p no:cacheprovider

# ruff with the rules of pyproject.toml ([tool.ruff]); make test runs it first
lint: $(STAMP)
	$(BIN)/ruff check .

test: $(STAMP)
	$(BIN)/ruff check .
	$(MAKE) -j2 --output-sync=target test-shapes test-rest
	$(MAKE) test-mpi

test-shapes: $(STAMP)
	DEM_TEST_WARM=0 $(PYTEST) --durations=8 --basetemp="$$(mktemp -d)/t" $(SHAPE_TESTS)
	$(PYTEST) --basetemp="$$(mktemp -d)/t" $(DOC_TESTS) -k "not ($(DOC_REST))"
	$(PYTEST) --doctest-modules dem hmm

test-rest: $(STAMP)
	$(PYTEST) --durations=8 --basetemp="$$(mktemp -d)/t" tests --ignore=tests/mpi \
		$(addprefix --ignore=,$(SHAPE_TESTS) $(DOC_TESTS))
	$(PYTEST) --basetemp="$$(mktemp -d)/t" $(DOC_TESTS) -k "$(DOC_REST)"

test-mpi: $(STAMP)
	NUMBA_NUM_THREADS=1 $(BIN)/mpiexec -n 2 $(BIN)/python -m mpi4py -m pytest -q -p no:cacheprovider tests/mpi

# Every page of docs/ as written, the long commands included (about 30 minutes).
docs-walk: $(STAMP)
	$(PYTEST) tests/test_tutorial.py tests/test_doc_pages.py tests/walk/walk_docs.py \
		tests/walk/walk_paraview.py

bench: $(STAMP)
	$(BIN)/python benchmarks/dem_throughput.py
	BASE=a7808d7 CODES=dem $(BIN)/python benchmarks/dem_throughput.py
	$(BIN)/python benchmarks/dt_speed_accuracy.py
	$(BIN)/python benchmarks/neighbor_backends.py
	$(BIN)/python benchmarks/step_profile.py
	BASE=a7808d7 STEPS=200 ROUNDS=5 $(BIN)/python benchmarks/step_profile.py
	$(BIN)/python benchmarks/contact_speed_accuracy.py
	$(BIN)/python benchmarks/shape_throughput.py
	$(BIN)/python benchmarks/porous_verification.py
	$(BIN)/python benchmarks/undrained_element.py
	$(BIN)/python benchmarks/porous_coupling.py
	$(BIN)/python benchmarks/shape_limits.py
	$(BIN)/python benchmarks/rve_call.py
	$(BIN)/python benchmarks/shape_rve_chunks.py
	$(BIN)/python benchmarks/mpi_scaling.py
	DIMS="2 3" $(BIN)/python benchmarks/rve_vs_yade.py
	$(BIN)/python benchmarks/rve_size_accuracy.py
	DIM=3 $(BIN)/python benchmarks/rve_size_accuracy.py
	$(BIN)/python benchmarks/rve_step_limit.py
	$(BIN)/python benchmarks/hmm_vs_femxdem.py
	DIM=3 $(BIN)/python benchmarks/hmm_vs_femxdem.py
	$(BIN)/python benchmarks/hmm_vs_femxdem_up.py
	$(BIN)/python benchmarks/undrained_biaxial.py
	$(BIN)/python benchmarks/hmm_tangent_adaptive.py
	$(BIN)/python benchmarks/footing_kinematics.py
	$(BIN)/python benchmarks/retaining_wall_reference.py
	CELLS=40x20 $(BIN)/python benchmarks/retaining_wall_reference.py
	$(BIN)/python benchmarks/demo_kinematics.py
	$(BIN)/python benchmarks/pd_lammps.py
	$(BIN)/python benchmarks/pd_kirsch.py
	$(BIN)/python benchmarks/pd_surface_effect.py
	$(BIN)/python benchmarks/stability_map.py
	$(BIN)/python benchmarks/angle_of_repose.py
	$(BIN)/python benchmarks/oblique_impact.py
	$(BIN)/python benchmarks/rolling_stop.py
	BASE=7fd19e3 RUNS=5 $(BIN)/python benchmarks/mesh_throughput.py
	$(BIN)/python benchmarks/hopper_beverloo.py
	$(BIN)/python benchmarks/cold_start.py
	$(BIN)/python benchmarks/cold_walk.py
	$(BIN)/python benchmarks/compile_memory.py
	BASE=090a134 NO_PARALLEL=1 $(BIN)/python benchmarks/loop_compile.py
	BASE=5972a47 $(BIN)/python benchmarks/loop_compile.py
	BASE=d8953e6 $(BIN)/python benchmarks/loop_compile.py
	$(BIN)/python benchmarks/law_call.py
	$(BIN)/python benchmarks/output_driver.py
	$(BIN)/python benchmarks/triaxial_3d.py
	$(BIN)/python benchmarks/cost_model.py

clean:
	rm -rf $(VENV) .numba_cache .pytest_cache output
