"""Runs that stop once the particles are at rest.

A poured or settling packing needs as many steps as it takes, not a number guessed in
advance: :func:`run_until_rest` runs at most ``n_steps`` and stops at the first check
where every free particle is slower than ``speed`` [m/s], spin included (the speed of
its surface, ``|omega| r``, so a sphere that rolls is not at rest). It is what the
``[simulation] rest_speed`` key of a scene file does (``dem run``).
"""

import time

import numpy as np

from .shapes import Shape
from .progress import progress_bar

__all__ = ["largest_speed", "run_chunked", "run_until_rest"]

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
    """Run ``sim`` at most ``n_steps`` steps, stopping at the first check where
    :func:`largest_speed` is below ``speed`` [m/s]. The checks fall on the steps that
    are multiples of ``every``, so that a run continued from a checkpoint checks where
    the uninterrupted one did.

    Returns the steps run and whether the particles came to rest.
    """
    if not speed > 0.0:
        raise ValueError(f"speed must be > 0 m/s, got {speed}")
    return run_chunked(sim, n_steps, speed, every=every, progress=progress)


def run_chunked(sim, n_steps, speed=None, every=CHECK_EVERY, progress=None, marks=(),
                after=None, seconds=0.5):
    """Run ``sim`` at most ``n_steps`` steps in chunks; what ``dem run`` does.

    A chunk ends at the next step any of ``marks`` (triggers with ``next_after``, e.g.
    a checkpoint's) asks for, at the next multiple of ``every`` when ``speed`` [m/s]
    is given (then the run stops once :func:`largest_speed` is below it), and after
    about ``seconds`` of wall time, so that ``after(sim)``, called at the end of every
    chunk, can answer a signal promptly. Chunking does not change the result: the
    steps are those of one :meth:`dem.Simulation.run`.

    Returns the steps run and whether the particles came to rest (False without
    ``speed``).
    """
    every = max(1, int(every))
    bar = progress_bar(n_steps, progress)
    start, end = sim.step, sim.step + int(n_steps)
    size = every  # steps per chunk, adapted to take about `seconds`
    try:
        while sim.step < end:
            stop = min([end, sim.step + size] + [m.next_after(sim.step) for m in marks])
            if speed is not None:
                stop = min(stop, (sim.step // every + 1) * every)
            t0, n = time.perf_counter(), stop - sim.step
            sim.run(n, progress=False)
            wall = time.perf_counter() - t0
            size = max(1, min(4 * size, int(n * seconds / wall))) if wall > 0 else 4 * size
            if bar is not None:
                bar.update(n)
            if after is not None:
                after(sim)
            if speed is not None and sim.step % every == 0 and largest_speed(sim) < speed:
                return sim.step - start, True
    finally:
        if bar is not None:
            bar.close()
    return sim.step - start, False
