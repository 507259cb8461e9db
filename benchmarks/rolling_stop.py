"""Rolling resistance against its analytic stopping distance and angle.

A sphere (disk in 2D; R = 1 cm, 2500 kg/m^3) resting on a plane is launched rolling
without slip at 0.2 m/s under rolling friction mu_roll = 0.1 (linear law, kn = 1e7 m
N/m, mu = 0.5): under the constant moment mu_roll R m g it decelerates at
``mu_roll g / (1 + I / (m R^2))`` and stops after ``v0^2 / (2 a)``. With twisting
friction mu_twist = 0.2 alone, a sphere spinning at 20 rad/s about the normal turns
``I w0^2 / (2 mu_twist R m g)`` before it stops. The same scenes as
tests/dem/test_rolling_resistance.py, which asserts 0.1 % (distance) and 1 % (angle);
this script reports the measured errors. Writes benchmarks/results/rolling_stop.json
(keys ``distance_error`` per dimension and dashpot, ``angle_error``).
Run: python benchmarks/rolling_stop.py
"""

import math
import sys
from pathlib import Path

import numpy as np

import dem

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

R, RHO, G = 0.01, 2500.0, 9.81
OUT = C.RESULTS / "rolling_stop.json"


def scene(dim, rolling, v=None, w=None):
    up = np.eye(dim)[-1]
    m = RHO * (4.0 / 3.0 * math.pi * R**3 if dim == 3 else math.pi * R**2)
    kn = 1e7 * m
    law = dem.LinearSpring(kn=kn, kt=0.4 * kn, mu=0.5, restitution=0.5,
                           rolling=dem.Rolling(**rolling))
    b = dem.Bodies.spheres([(R - G * m / kn) * up], radius=R, density=RHO,
                           vel=None if v is None else [v])
    if w is not None:
        b.ang_vel[0] = w
    b.add_plane(np.zeros(dim), up)
    box = dem.Domain(np.full(dim, -0.5), np.full(dim, 0.5), np.eye(dim)[0] > 0)
    return dem.Simulation(b, law, gravity=-G * up, box=box), m


def main():
    v0, mu_r = 0.2, 0.1
    out = {"distance_error": {}}
    for dim in (2, 3):
        for eta in (0.0, 0.5):
            w = [-v0 / R] if dim == 2 else [0.0, v0 / R, 0.0]
            sim, _ = scene(dim, {"mu_roll": mu_r, "eta_roll": eta}, np.eye(dim)[0] * v0, w)
            a = mu_r * G / (1.0 + (0.4 if dim == 3 else 0.5))
            sim.run(int(1.3 * v0 / a / sim.dt), progress=False)
            err = sim.bodies.pos[0, 0] / (v0**2 / (2.0 * a)) - 1.0
            out["distance_error"][f"{dim}D eta_roll={eta}"] = err
            print(f"{dim}D, eta_roll = {eta}: stopping distance {err:+.2e} from analytic")
    w0, mu_w = 20.0, 0.2
    sim, m = scene(3, {"mu_roll": 0.0, "mu_twist": mu_w, "eta_roll": 0.5}, w=[0.0, 0.0, w0])
    inertia = 0.4 * m * R**2
    moment = mu_w * R * m * G
    angle = 0.0
    for _ in range(int(1.3 * inertia * w0 / moment / sim.dt)):
        sim.run(1, progress=False)
        angle += sim.bodies.ang_vel[0, 2] * sim.dt
    out["angle_error"] = angle / (inertia * w0**2 / (2.0 * moment)) - 1.0
    print(f"twisting: angle turned {out['angle_error']:+.2e} from analytic")
    out |= {"machine": C.machine_info(), "software": C.our_versions(), "date": C.now()}
    C.write_json(OUT, out)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    main()
