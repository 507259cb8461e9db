"""The cost model of the dry runs (dem.cost) and the notice of a cold compile
and its compilation in a child process (dem._jit.prepare)."""

import importlib.util
import io
import logging
import os

import numpy as np
import pytest

from dem import _jit, cost


def test_rve_time_grows_with_its_work():
    base = cost.rve_test_seconds(200, 2, 100, 1e-3, 1e-5, servo=True)
    assert cost.rve_test_seconds(400, 2, 100, 1e-3, 1e-5, servo=True) > base
    assert cost.rve_test_seconds(200, 2, 200, 1e-3, 1e-5, servo=True) > base
    assert cost.rve_test_seconds(200, 3, 100, 1e-3, 1e-5, servo=True) > base
    assert cost.rve_test_seconds(200, 2, 100, 1e-3, 1e-5, servo=False) < base
    # a packing read from a file is not consolidated
    assert cost.rve_test_seconds(200, 2, 100, 1e-3, 1e-5, servo=True,
                                 generated=False) == pytest.approx(
        base - 200 * cost.CONSOLIDATION_S[2])
    # steps: a load step per max_step_strain of the increment, then the relaxation
    assert cost.rve_call_steps(-2.5e-4, 1e-5) == 25 + cost.RELAX_STEPS


def test_multiscale_time_is_calls_times_call_cost():
    one = cost.fe2_seconds(60, 2, 1, 1, 1e-5, generated=False)
    many = cost.fe2_seconds(60, 2, 32, 8, 1e-5, generated=False)
    assert many == pytest.approx(32 * 8 * one)
    steps = cost.CALLS_PER_STEP * cost.rve_call_steps(1e-4, 1e-5)
    assert one == pytest.approx(cost.CALLS_PER_STEP * cost.RVE_CALL_S
                                + cost.rve_seconds(60, steps, 2))


def test_an_unrelaxed_call_costs_its_load_steps_only():
    """relax = false (YADE FEMxDEM's call) takes the load steps and no relaxation: a
    1e-4 increment at 1e-5 a step is 10 steps, not 110."""
    assert cost.rve_call_steps(1e-4, 1e-5, relax=False) == 10
    assert cost.rve_call_steps(1e-4, 1e-5, servo=True, relax=False) == 10
    relaxed = cost.fe2_seconds(100, 2, 1, 1, 1e-5, generated=False)
    unrelaxed = cost.fe2_seconds(100, 2, 1, 1, 1e-5, generated=False, relax=False)
    assert unrelaxed == pytest.approx(cost.CALLS_PER_STEP * cost.RVE_CALL_S
                                      + cost.rve_seconds(100, cost.CALLS_PER_STEP * 10, 2))
    assert relaxed - unrelaxed == pytest.approx(
        cost.rve_seconds(100, cost.CALLS_PER_STEP * cost.RELAX_STEPS, 2))


def test_the_extrapolated_predictor_makes_fewer_calls():
    tangent = cost.fe2_seconds(100, 3, 8, 4, 1e-5, generated=False)
    extrapolated = cost.fe2_seconds(100, 3, 8, 4, 1e-5, generated=False,
                                    predictor="extrapolated")
    assert extrapolated == pytest.approx(
        tangent * cost.CALLS_PER_STEP_EXTRAPOLATED / cost.CALLS_PER_STEP)


def test_shapes_cost_more_than_spheres():
    assert cost.run_seconds(1000, 100, 3, shaped=True) > cost.run_seconds(1000, 100, 3)


@pytest.mark.parametrize("seconds, text", [(0.2, "under 1 s"), (7.26, "7.3 s"),
                                           (99.0, "99 s"), (100.0, "2 min"),
                                           (3599.0, "60 min"), (7200.0, "2.0 h"),
                                           (86400.0 * 3, "3 days")])
def test_durations_read_as_a_person_would(seconds, text):
    assert cost.duration(seconds) == text


def test_the_time_line_logs_the_seconds(caplog):
    with caplog.at_level(logging.INFO, logger="dem.cost"):
        line = cost.time_line(752.0, at_most=True)
    assert line == "time at most 13 min on one core (cost model, warm kernels)"
    assert f"cost model: {752.0 + cost.STARTUP_S:.4g} s on one core" in caplog.text


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def _fresh_kernel(tmp_path, monkeypatch, name):
    """A cached kernel in a module of its own, with its own disk cache, made by a
    factory with a recipe (so that :func:`dem._jit.prepare` may compile it apart)."""
    monkeypatch.setattr(_jit.numba.config, "CACHE_DIR", str(tmp_path / "cache"))
    src = tmp_path / f"{name}.py"
    src.write_text("import numba\n"
                   "from dem._jit import kernel, recipe\n\n\n"
                   "def make(k):\n"
                   "    @kernel(parallel=True)\n"
                   "    def scaled_sum(x):\n"
                   "        s = 0.0\n"
                   "        for i in numba.prange(x.shape[0]):\n"
                   "            s += k * x[i]\n"
                   "        return s\n"
                   "    return recipe(scaled_sum, make, k)\n")
    monkeypatch.syspath_prepend(str(tmp_path))  # for the child process too
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(tmp_path)] + os.environ.get("PYTHONPATH", "").split(os.pathsep)))
    spec = importlib.util.spec_from_file_location(name, src)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.make(2.0)


X = np.arange(4.0)


def _sig(dispatcher):
    return tuple(dispatcher.typeof_pyval(a) for a in (X,))


def test_a_cold_loop_is_announced_once_and_compiled_in_a_child(tmp_path, monkeypatch):
    twice = _fresh_kernel(tmp_path, monkeypatch, "cold_kernel_a")
    monkeypatch.setattr(_jit, "_announced", set())
    monkeypatch.delenv("PMI_RANK", raising=False)
    err = _Terminal()
    monkeypatch.setattr(_jit.sys, "stderr", err)
    assert not _jit._cached(twice, _sig(twice))
    _jit.prepare(twice, (X,), "sphere")
    _jit.prepare(twice, (X,), "sphere")
    assert err.getvalue() == (f"dem: compiling the sphere kernels: first run only, "
                              f"about {_jit.COMPILE_S['sphere']} s\n")
    # the child wrote the disk cache; this process has compiled nothing, and loads it
    assert _jit._cached(twice, _sig(twice))
    assert not twice.overloads
    assert twice(X) == 12.0
    assert twice.stats.cache_hits[_sig(twice)] == 1


def test_without_the_child_the_loop_compiles_here(tmp_path, monkeypatch):
    twice = _fresh_kernel(tmp_path, monkeypatch, "cold_kernel_d")
    monkeypatch.setattr(_jit, "APART", False)
    _jit.prepare(twice, (X,), "sphere")
    assert not _jit._cached(twice, _sig(twice))
    assert twice(X) == 12.0
    assert twice.stats.cache_misses[_sig(twice)] == 1


def test_warm_kernels_and_other_ranks_say_nothing(tmp_path, monkeypatch):
    twice = _fresh_kernel(tmp_path, monkeypatch, "cold_kernel_b")
    err = _Terminal()
    monkeypatch.setattr(_jit.sys, "stderr", err)
    monkeypatch.setattr(_jit, "_announced", set())
    monkeypatch.setenv("PMI_RANK", "1")
    monkeypatch.setattr(_jit, "APART", False)
    _jit.prepare(twice, (X,), "shape")  # cold, but not rank 0
    twice(X)
    monkeypatch.setattr(_jit, "_announced", set())
    monkeypatch.delenv("PMI_RANK")
    _jit.prepare(twice, (X,), "shape")  # rank 0, but warm
    assert err.getvalue() == ""


def test_off_a_terminal_the_notice_is_logged(tmp_path, monkeypatch, caplog):
    twice = _fresh_kernel(tmp_path, monkeypatch, "cold_kernel_c")
    monkeypatch.setattr(_jit, "_announced", set())
    monkeypatch.delenv("PMI_RANK", raising=False)
    monkeypatch.setattr(_jit, "APART", False)
    monkeypatch.setattr(_jit.sys, "stderr", io.StringIO())
    with caplog.at_level(logging.INFO, logger="dem._jit"):
        _jit.prepare(twice, (X,), "shape")
    assert _jit.sys.stderr.getvalue() == ""
    assert "compiling the shape kernels: first run only" in caplog.text
