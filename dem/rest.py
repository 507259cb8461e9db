"""Runs that stop once the particles are at rest.

A poured or settling packing needs as many steps as it takes, not a number guessed in
advance: :func:`run_until_rest` runs at most ``n_steps`` and stops at the first check
where every free particle is slower than ``speed`` [m/s], spin included (the speed of
its surface, ``|omega| r``, so a sphere that rolls is not at rest). It is what the
``[simulation] rest_speed`` key of a scene file does (``dem run``).
"""

import numpy as np

from .shapes import Shape
from .simulation import progress_bar

__all__ = ["largest_speed", "run_until_rest"]

#: steps between two checks of the speeds
CHECK_EVERY = 100


def largest_speed(sim):
    """The largest speed [m/s] of a free particle of ``sim``: the larger of its centre's
    speed and its surface's speed of rotation ``|omega| r`` (0.0 without particles).
    Walls and fixed bodies are left out."""
    b = sim.bodies
    free = ~b.is_fixed & (b.kind != Shape.PLANE)
    if not free.any():
        return 0.0
    v = np.linalg.norm(b.vel[free], axis=1)
    w = np.linalg.norm(b.ang_vel[free].reshape(int(free.sum()), -1), axis=1)
    return float(max(v.max(), (w * b.radius[free]).max()))


def run_until_rest(sim, n_steps, speed, every=CHECK_EVERY, progress=None):
    """Run ``sim`` at most ``n_steps`` steps, stopping at the first check (every
    ``every`` steps) where :func:`largest_speed` is below ``speed`` [m/s].

    Returns the steps run and whether the particles came to rest.
    """
    if not speed > 0.0:
        raise ValueError(f"speed must be > 0 m/s, got {speed}")
    every = max(1, int(every))
    bar = progress_bar(n_steps, progress)
    done = 0
    try:
        while done < n_steps:
            chunk = min(every, n_steps - done)
            sim.run(chunk, progress=False)
            done += chunk
            if bar is not None:
                bar.update(chunk)
            if largest_speed(sim) < speed:
                return done, True
    finally:
        if bar is not None:
            bar.close()
    return done, False
