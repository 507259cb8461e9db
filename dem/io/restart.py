"""Checkpoints of a scene run, and ``dem run --restart``.

With ``[output] checkpoint_every = N`` a scene run writes ``checkpoint.h5`` beside its
particle file every N steps, at its end, and when SIGINT or SIGTERM stops it. The file
is a :func:`dem.io.save_checkpoint` checkpoint with two additions:

* the attribute ``scene_digest``: what the scene asks for, the step count and the
  ``[output]`` section left out, so that a restart refuses a checkpoint of another
  scene but may run longer (``--steps``) or write elsewhere;
* the group ``/insert`` (a scene with ``[insert]``): the particles inserted so far and
  the random generator's state, so that the insertion goes on as it would have.

``dem run --restart`` rebuilds the simulation from the checkpoint and runs on to the
scene's step count; the particle file keeps its frames up to the checkpoint's step
and the new ones follow. The continued run is the uninterrupted one bit for bit.
"""

import copy
import hashlib
import json
import os

import h5py

from .checkpoint import FORMAT, load_checkpoint, read_group, save_checkpoint

__all__ = ["CHECKPOINT", "load_scene_checkpoint", "save_scene_checkpoint", "scene_digest"]

#: the checkpoint's file name, in the directory of the particle file
CHECKPOINT = "checkpoint.h5"


def scene_digest(scene):
    """A hash of what a validated scene asks for, less what a restart may change:
    ``[simulation] steps``, ``[output]`` and the file's own name."""
    s = copy.deepcopy({k: v for k, v in scene.items() if k not in ("output", "source")})
    s.get("simulation", {}).pop("steps", None)
    particles = s.get("particles") or {}
    if particles.get("file"):  # resolved against the scene's folder: keep the name
        particles["file"] = os.path.basename(particles["file"])
    text = json.dumps(s, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def _inserter(sim):
    from ..insertion import Inserter

    found = [c for c in sim.controllers if isinstance(c, Inserter)]
    return found[0] if found else None


def save_scene_checkpoint(sim, path, scene, config=None):
    """Write the checkpoint of a scene run (atomically); ``config`` is the scene's text."""
    digest = scene_digest(scene)
    inserter = _inserter(sim)

    def extra(f):
        f.attrs["scene_digest"] = digest
        if inserter is not None:
            g = f.create_group("insert")
            state = inserter.state()
            g.attrs["state"] = json.dumps({k: v for k, v in state.items() if k != "ids"})
            g.create_dataset("ids", data=state["ids"], dtype="i8")
            g["ids"].attrs["unit"] = "1"

    return save_checkpoint(sim, path, extra=extra, config=config)


def checkpoint_step(path):
    """The step a checkpoint holds, or None where there is no readable one."""
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != FORMAT:
                return None
            return int(f.attrs["step"])
    except (OSError, KeyError, TypeError, ValueError):
        return None


def _digest(path):
    with h5py.File(path, "r") as f:
        digest = f.attrs.get("scene_digest")
    return digest.decode() if isinstance(digest, bytes) else digest


def load_scene_checkpoint(path, scene, built):
    """The simulation of ``built`` (the scene's, just built) continued from the
    checkpoint at ``path``: its contact law, controllers and threads, the saved state.

    Raises ValueError (one line) for a missing file, a file that is not a checkpoint,
    or a checkpoint of another scene.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise ValueError(f"--restart: no checkpoint {path} (a run writes one when "
                         f"[output] checkpoint_every is set)")
    if checkpoint_step(path) is not None and _digest(path) != scene_digest(scene):
        raise ValueError(f"--restart: {path} was written for another scene (only "
                         f"[simulation] steps and [output] may change on a restart)")
    sim = load_checkpoint(path, built.model, controllers=built.controllers,
                          state_objects=built.state_objects)
    sim.threads = built.threads
    inserter = _inserter(sim)
    if inserter is not None:
        g = read_group(path, "insert")
        inserter.restore(json.loads(g["attrs"]["state"]) | {"ids": g["data"]["ids"]})
    return sim
