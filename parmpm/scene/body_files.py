"""Bodies read from files (issue 30): a volume mesh (``shape = "mesh"``), a closed surface
(``shape = "surface"``, 3D) or listed particles (``shape = "particles"``) — their scene keys,
and the in-process cache that reads each file once.

The resolved scene holds only the file's absolute path and the body's small keys (it is written
as ``scene.toml`` and stored in checkpoints, so it must stay TOML); whatever needs the file's
contents — the schema's "inside the grid" check, :meth:`parmpm.scene.records.Body.bounds`, the
overlap check, the memory estimate, seeding — asks this module, which reads the file on first
use and keeps it keyed by path, size and modification time (a file changed between the check
and the run is read again, not mixed up). A relative ``file`` is relative to the scene file's
folder (a scene given as text or a built-in: the working directory).
"""
from __future__ import annotations

import functools
import math
import os
import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any, NamedTuple

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.core.log import get_logger
from parmpm.scene.check import Checker, show

log = get_logger(__name__)

#: each file shape's own keys, and the dimensions it exists in
FILE_KEYS = {"mesh": ("file", "groups", "split"), "surface": ("file",),
             "particles": ("file", "step")}
FILE_DIMS = {"mesh": (2, 3), "surface": (3,), "particles": (1, 2, 3)}
#: the most sub-divisions per element edge (split^d times the particles of each element)
MAX_SPLIT = 16
#: the most particles a meshed body may make (as a particle file may hold)
MAX_MESH_PARTICLES = 2**31


class Listed(NamedTuple):
    """A body given point by point, in file order: positions ``x`` (n, d), reference volumes
    ``vol`` (n,) and, where the file gives them, ``velocity`` (n, d), material names
    ``material`` (n,) and deformation gradients ``F`` (n, d, d)."""
    x: np.ndarray
    vol: np.ndarray
    velocity: np.ndarray | None = None
    material: np.ndarray | None = None
    F: np.ndarray | None = None


def scene_folder(where: str) -> Path:
    """The folder a body's relative ``file`` is read from: the scene file's (``where`` is the
    checker's ``scene '<source>'``), else the working directory."""
    m = re.fullmatch(r"scene '(.*)'", where, re.DOTALL)
    source = m.group(1) if m else ""
    if source and not source.startswith("builtin:") and Path(source).is_file():
        return Path(source).resolve().parent
    return Path.cwd()


def _stamp(path: str) -> tuple:
    try:
        st = os.stat(path)
    except OSError:
        return (path, None, None)
    return (path, st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=8)
def _mesh_file(stamp: tuple, dim: int, groups: tuple | None):
    """The mesh and its bounds (the nodes of its cells)."""
    from parmpm.io.mesh_file import read_volume_mesh

    mesh = read_volume_mesh(stamp[0], dim, None if groups is None else list(groups))
    used = np.unique(np.concatenate([b.cells.ravel() for b in mesh.blocks]))
    nodes = mesh.points[used]
    return mesh, (nodes.min(axis=0).tolist(), nodes.max(axis=0).tolist())


@functools.lru_cache(maxsize=4)
def _mesh(stamp: tuple, dim: int, groups: tuple | None, split: int) -> Listed:
    from parmpm.geometry.mesh import mesh_particles

    mesh = _mesh_file(stamp, dim, groups)[0]
    x, vol, _ = mesh_particles(mesh.points, mesh.blocks, split, label=f"mesh '{stamp[0]}'")
    return Listed(x, vol)


def _groups_of(body) -> tuple | None:
    return None if body.groups is None else tuple(body.groups)


def count(body, dim: int) -> int:
    """How many particles a mesh or particle body makes, without making them."""
    from parmpm.geometry.mesh import particles_per_element

    if body.shape == "particles":
        return int(listed(body, dim).x.shape[0])
    mesh = _mesh_file(_stamp(body.file), dim, _groups_of(body))[0]
    return sum(len(b.cells) * particles_per_element(b.cell_type, int(body.split))
               for b in mesh.blocks)


@functools.lru_cache(maxsize=8)
def _surface(stamp: tuple):
    from parmpm.geometry.surface import check_surface
    from parmpm.io.surface_file import read_surface

    V, T = read_surface(stamp[0])
    return V, T, check_surface(V, T, stamp[0])


@functools.lru_cache(maxsize=8)
def _particles(stamp: tuple, dim: int, step: int | None) -> tuple[Listed, tuple, str]:
    from parmpm.io.particle_file import read_particle_file

    p = read_particle_file(stamp[0], dim, step=step)
    listed = Listed(p.x, p.reference_volume(), p.velocity, p.material, p.F)
    return listed, (p.x.min(axis=0).tolist(), p.x.max(axis=0).tolist()), p.repeats


def listed(body, dim: int) -> Listed:
    """A mesh's or particle file's points (read once per process)."""
    if body.shape == "mesh":
        return _mesh(_stamp(body.file), dim, _groups_of(body), int(body.split))
    return _particles(_stamp(body.file), dim, body.step)[0]


def surface(body):
    """A surface body's ``(vertices, triangles, summary)`` (read once per process)."""
    return _surface(_stamp(body.file))


def bounds(body, dim: int) -> tuple[list, list]:
    """Axis-aligned bounds of a file body: a mesh's nodes, a surface's triangles, the points."""
    if body.shape == "surface":
        s = surface(body)[2]
        return list(s.lo), list(s.hi)
    if body.shape == "mesh":
        return _mesh_file(_stamp(body.file), dim, _groups_of(body))[1]
    return _particles(_stamp(body.file), dim, body.step)[1]


def inside(body, dim: int, x) -> np.ndarray:
    """Which points lie inside a surface body (:func:`parmpm.geometry.surface.inside_surface`);
    a mesh or particle body has no inside test here (the overlap check skips it as the outer body)."""
    from parmpm.geometry.surface import inside_surface

    x = np.asarray(x, float).reshape(-1, dim)
    if body.shape != "surface":
        return np.zeros(len(x), bool)
    V, T, _ = surface(body)
    return inside_surface(V, T, x)


# ---------------------------------------------------------------- the scene keys


def check_file_body(c: Checker, key: str, t: dict, dim: int, shape: str,
                    materials: dict) -> tuple[dict, list, list]:
    """A file body's resolved keys (``file`` absolute, ``groups``, ``split``, ``step``) and its
    bounds; reads the file, so that every problem with it is one line naming ``key.file``."""
    fkey = f"{key}.file"
    name = c.string(fkey, c.required(key, t, "file", "a path to a file (relative: to the scene's "
                                                     "folder)"))
    if not name.strip():
        c.expected(fkey, "a path to a file", name)
    path = Path(os.path.expanduser(name))
    if not path.is_absolute():
        path = scene_folder(c.where) / path
    out: dict[str, Any] = {"file": os.path.abspath(path)}
    if shape == "mesh":
        out["groups"] = _groups(c, f"{key}.groups", t.get("groups"))
        out["split"] = c.integer(f"{key}.split", t.get("split", 1),
                                 f"an integer from 1 to {MAX_SPLIT}", lambda s: 1 <= s <= MAX_SPLIT)
    if shape == "particles":
        step = t.get("step")
        out["step"] = None if step is None else c.integer(f"{key}.step", step,
                                                          "an integer >= 0 (a run's step)",
                                                          lambda s: s >= 0)
    view = _view(shape, out)
    try:
        lo, hi = _check_surface(key, view) if shape == "surface" else bounds(view, dim)
        n = count(view, dim) if shape == "mesh" else 0
        if shape == "mesh" and n <= MAX_MESH_PARTICLES:  # its elements' checks (split 1: the same)
            _mesh(_stamp(view.file), dim, _groups_of(view), 1)
        data = listed(view, dim) if shape == "particles" else None
    except SceneError as exc:
        c.fail(fkey, str(exc))
    note = _particles(_stamp(view.file), dim, view.step)[2] if data is not None else ""
    if note:  # rows at one position: the body's mass counted again there
        _warn_once(f"{fkey}: {note}")
    names = None if data is None else data.material
    moving = [k for k in ("velocity", "angular_velocity", "velocity_gradient") if k in t]
    if data is not None and data.velocity is not None and moving:
        c.fail(f"{key}.{moving[0]}", f"the particle file '{out['file']}' gives every particle's "
                                     "velocity; expected no initial velocity keys (or a file "
                                     "without velocities)")
    if n > MAX_MESH_PARTICLES:
        c.fail(f"{key}.split", f"{out['split']} makes {n} particles, more than "
                               f"{MAX_MESH_PARTICLES}; expected a smaller split")
    if names is not None:
        for name in np.unique(names):
            if str(name) not in materials:
                c.fail(fkey, f"particle file '{out['file']}' names material {show(str(name))}, "
                             "which the scene does not define (defined: "
                             + ", ".join(show(m) for m in materials) + ")")
    return out, lo, hi


def _view(shape: str, keys: dict) -> SimpleNamespace:
    """The few fields of a body the loaders read, before its record exists."""
    return SimpleNamespace(shape=shape, file=keys["file"], groups=keys.get("groups"),
                           split=keys.get("split", 1), step=keys.get("step"))


def _groups(c: Checker, key: str, raw: Any) -> list | None:
    if raw is None:
        return None
    what = "a non-empty list of group names or ids (Gmsh physical groups, cell sets)"
    if not isinstance(raw, list) or not raw:
        c.expected(key, what, raw)
    for g in raw:
        if isinstance(g, bool) or not isinstance(g, (str, int)):
            c.expected(key, what, raw)
    return list(raw)


def _check_surface(key: str, body) -> tuple[list, list]:
    """The surface's bounds; a warning when it is not closed and consistently oriented."""
    _, _, s = surface(body)
    problems = [f"{n} {what} edges" for n, what in ((s.open_edges, "open"),
                                                  (s.nonmanifold_edges, "non-manifold"),
                                                  (s.misoriented_edges, "misoriented")) if n]
    if problems:
        _warn_once(f"{key}.file: surface '{body.file}' is not a closed, consistently oriented "
                   f"surface ({', '.join(problems)}); its inside is the generalised winding "
                   "number's guess near those edges")
    return list(s.lo), list(s.hi)


@functools.lru_cache(maxsize=64)
def _warn_once(line: str) -> None:
    """Logged once per process, by rank 0 only (every rank checks the scene)."""
    try:
        from mpi4py import MPI
        rank = MPI.COMM_WORLD.Get_rank() if MPI.Is_initialized() else 0
    except ImportError:  # pragma: no cover - MPI is a dependency
        rank = 0
    if rank == 0:
        log.warning("%s", line)


def listed_volume(body, dim: int) -> float:
    """Total reference volume of a mesh's or particle file's points (the memory and speed checks)."""
    return float(math.fsum(listed(body, dim).vol))
