"""A parmpm run's own output as a particle file: a snapshot series' ``.h5`` (or its ``.xdmf``)
or a checkpoint, so that one run's particles start another.

* **Snapshot** (:mod:`parmpm.io.xdmf`): one step, the last by default (``step=`` picks another
  by the run's step number, the ``step_<step>`` group): ``x``, ``volume`` (the current volume
  ``vol0 · det F``), ``velocity`` and ``F``, in global-id order (``gid``; a series written in
  parts merged). A snapshot stores no material (its file has no scene), so ``material`` is
  ``None``: the scene must name the body's material.
* **Checkpoint** (:mod:`parmpm.io.checkpoint`): its one step: ``x``, ``v``, ``F``, the volume
  ``vol0 · det F`` (so :meth:`ParticleData.reference_volume` gives ``vol0`` back up to
  rounding) and the material names (its ``mat`` rows are the sorted names of its stored
  scene's materials, :func:`parmpm.materials.material_table`), in global-id order.

Neither carries the stress, damage, domain vectors or APIC's affine matrix into the new run: the
particles start unstressed from their positions, volumes, velocities and ``F`` (``parmpm
restart`` continues a run exactly).
"""
from __future__ import annotations

import tomllib

import numpy as np

from parmpm.core.errors import ParmpmError
from parmpm.io.particle_file.data import fail, finish


def _pick(label: str, steps: np.ndarray, step: int | None) -> int:
    """The index of run step ``step`` among ``steps`` (None: the last)."""
    if len(steps) == 0:
        fail(label, "is a parmpm snapshot series with no snapshot written; expected at least one step")
    if step is None:
        return len(steps) - 1
    hit = np.flatnonzero(steps == int(step))
    if hit.size == 0:
        shown = ", ".join(str(s) for s in steps[:3]) + (" ... " + str(steps[-1])
                                                          if len(steps) > 3 else "")
        fail(label, f"has no snapshot of step {int(step)}; its steps are {shown}")
    return int(hit[-1])


def read_snapshot(label: str, path, dim: int, step: int | None):
    """One step of a snapshot series (the last by default)."""
    from parmpm.io.xdmf.reader import load_snapshots

    try:
        s = load_snapshots(path)
        if s.dim != dim:
            fail(label, f"is a {s.dim}D parmpm snapshot series; this scene is {dim}D")
        k = _pick(label, s.steps, step)
        for name in ("x", "volume"):
            if name not in s:
                fail(label, f"snapshot step {int(s.steps[k])} has no field '{name}' (it holds "
                            f"{', '.join(s.fields)}); expected a run's snapshot (x, volume, ...)")
        fields = {"x": s["x"][k], "volume": s["volume"][k]}
        for name, key in (("velocity", "velocity"), ("F", "F")):
            if key in s:
                fields[name] = s[key][k]
        if "gid" in s:
            order = np.argsort(s["gid"][k], kind="stable")
            fields = {name: a[order] for name, a in fields.items()}
    except ParmpmError as exc:
        if str(exc).startswith(label):
            raise
        fail(label, str(exc))
    except (KeyError, ValueError, TypeError, OSError) as exc:  # h5py on damaged metadata
        fail(label, f"is a damaged parmpm snapshot series ({type(exc).__name__}: "
                    f"{(str(exc).splitlines() or [''])[0]})")
    source = (f"{label}, snapshot step {int(s.steps[k])} (t = {s.times[k]:.6g} s; snapshot "
              f"{k + 1} of {len(s)})")
    names = {key: f"field '{key}' of step {int(s.steps[k])}" for key in ("x", "volume", "velocity", "F")}
    return finish(label, source, fields, lambda i: f"particle {i} (in global-id order)", names)


def _materials(label: str, scene_text: str, rows: np.ndarray) -> np.ndarray:
    """The material name of every ``mat`` row, from the checkpoint's stored scene."""
    try:
        names = sorted(tomllib.loads(scene_text).get("materials", {}))
    except tomllib.TOMLDecodeError as exc:
        fail(label, f"its stored scene is not TOML ({exc}); cannot name the materials")
    if rows.size and (rows.min() < 0 or rows.max() >= len(names)):
        fail(label, f"material row {int(rows.max())} but the stored scene has {len(names)} "
                    "material(s); expected rows 0 .. n-1")
    return np.array(names, dtype=str)[rows] if names else np.zeros(rows.shape, dtype="U1")


def read_checkpoint(label: str, path, dim: int, step: int | None):
    """A checkpoint's particles (its one step)."""
    from parmpm.io.checkpoint.reader import CheckpointReader

    try:
        r = CheckpointReader(path, warn=False)
    except ParmpmError as exc:
        fail(label, str(exc))
    try:
        saved = int(r.attrs["step"])
        if r.dim != dim:
            fail(label, f"is a {r.dim}D parmpm checkpoint; this scene is {dim}D")
        if step is not None and int(step) != saved:
            fail(label, f"is the checkpoint of step {saved}, not of step {int(step)}")
        order = np.argsort(r.read("gid"), kind="stable")
        fields = {"x": r.read("x")[order], "velocity": r.read("v")[order],
                  "F": r.read("F")[order]}
        fields["volume"] = r.read("vol0")[order] * np.linalg.det(fields["F"])
        fields["material"] = _materials(label, str(r.attrs["scene"]), r.read("mat")[order])
        t = float(r.attrs["time"])
    except ParmpmError as exc:
        if str(exc).startswith(label):
            raise
        fail(label, str(exc))
    finally:
        r.close()
    names = {"x": "x", "volume": "vol0 * det F", "velocity": "v", "material": "mat", "F": "F"}
    names = {k: f"particles/{v}" for k, v in names.items()}
    source = f"{label}, checkpoint of step {saved} (t = {t:.6g} s)"
    return finish(label, source, fields, lambda i: f"particle {i} (in global-id order)", names)
