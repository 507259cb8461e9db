"""benchmarks/hopper_beverloo.py runs at its small size: an STL bin drains through its
orifice, the wider one faster, and Beverloo's fit gives a finite exponent."""

import runpy
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "hopper_beverloo.py"


def test_the_wider_orifice_drains_faster(monkeypatch):
    monkeypatch.setenv("HOPPER_SIZE", "small")
    bench = runpy.run_path(str(SCRIPT), run_name="bench")
    v, f = bench["bin_triangles"](1.0, 1.0, 0.25)
    assert f.shape == (16, 3) and v[f].reshape(-1, 3)[:, 2].min() == 0.0
    orifices, rates, n = bench["main"]()
    assert n > 100 and 0.0 < rates[0] < rates[1]
    assert np.isfinite(bench["beverloo_exponent"](orifices, rates))
