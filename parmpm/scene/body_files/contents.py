"""What a body file holds, read once per process: a mesh's points and bounds, a surface, a
particle file's rows — each read on first use and kept keyed by path, size and modification time
(a file changed between the check and the run is read again, not mixed up). A restart's body
whose file is gone or changed since the checkpoint is *detached*
(:mod:`parmpm.scene.recorded_files`): its bounds and count come from the checkpoint's record,
and whatever needs the contents refuses in one line.
"""
from __future__ import annotations

import contextlib
import contextvars
import functools
import math
from typing import NamedTuple

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.core.extremes import column_min_max
from parmpm.core.log import get_logger
from parmpm.scene import recorded_files
from parmpm.scene.recorded_files import stamp as _stamp  # the readers' cache key

log = get_logger(__name__)


class Listed(NamedTuple):
    """A body given point by point, in file order: positions ``x`` (n, d), reference volumes
    ``vol`` (n,) and, where the file gives them, ``velocity`` (n, d), material names
    ``material`` (n,) and deformation gradients ``F`` (n, d, d)."""
    x: np.ndarray
    vol: np.ndarray
    velocity: np.ndarray | None = None
    material: np.ndarray | None = None
    F: np.ndarray | None = None


@functools.lru_cache(maxsize=8)
def _mesh_file(stamp: tuple, dim: int, groups: tuple | None):
    """The mesh and its bounds (the nodes of its cells)."""
    from parmpm.io.mesh_file import read_volume_mesh

    mesh = read_volume_mesh(stamp[0], dim, None if groups is None else list(groups))
    used = np.zeros(len(mesh.points), bool)  # a mask, not np.unique: no sort of every cell's nodes
    for b in mesh.blocks:
        used[b.cells.ravel()] = True
    nodes = mesh.points[used]
    lo, hi = column_min_max(nodes)
    return mesh, (lo.tolist(), hi.tolist())


def volume_mesh(body, dim: int):
    """A mesh body's :class:`parmpm.io.mesh_file.VolumeMesh` (read once per process): the
    elements a parallel set-up deals out (:mod:`parmpm.driver.mesh_slices`)."""
    _attached(body, "making its particles")
    return _mesh_file(_stamp(body.file), dim, _groups_of(body))[0]


#: whether a mesh body's element checks wait for the set-up (:func:`deferred_element_checks`)
_DEFERRED = contextvars.ContextVar("parmpm_deferred_element_checks", default=False)


@contextlib.contextmanager
def deferred_element_checks():
    """Within: a mesh body's check reads the file (nodes, connectivity, groups, bounds, count)
    but leaves its elements' checks (degenerate, inverted, tangled) to the set-up, which makes
    every particle anyway. A parallel run's rank 0 resolves the scene so
    (:func:`parmpm.scene.agreement.load_shared_scene`): its set-up makes each rank's share of the
    particles on that rank (:mod:`parmpm.driver.mesh_slices`), and an element check here would
    make them all on rank 0, the O(N) pass the ranks wait for."""
    token = _DEFERRED.set(True)
    try:
        yield
    finally:
        _DEFERRED.reset(token)


def element_checks_deferred() -> bool:
    return _DEFERRED.get()


@functools.lru_cache(maxsize=4)
def _mesh(stamp: tuple, dim: int, groups: tuple | None, split: int) -> Listed:
    from parmpm.geometry.mesh import mesh_particles

    mesh = _mesh_file(stamp, dim, groups)[0]
    x, vol, _ = mesh_particles(mesh.points, mesh.blocks, split, label=f"mesh '{stamp[0]}'")
    return Listed(x, vol)


def _groups_of(body) -> tuple | None:
    return None if body.groups is None else tuple(body.groups)


def count(body, dim: int) -> int:
    """How many particles a mesh or particle body makes, without making them (a detached body's:
    as recorded; on a parallel run's other ranks: as rank 0 counted them)."""
    from parmpm.geometry.mesh import particles_per_element

    if recorded_files.detached(body):
        return recorded_files.recorded(body).count
    if (rec := recorded_files.shared(body)) is not None:  # rank 0 read it
        return rec.count
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
    lo, hi = column_min_max(p.x)
    return listed, (lo.tolist(), hi.tolist()), p.repeats


def _attached(body, needs: str) -> None:
    """Refuse to read a detached body's file (:func:`parmpm.scene.recorded_files.detached`)."""
    if recorded_files.detached(body):
        raise SceneError(f"the file '{body.file}' is gone or changed since the checkpoint this "
                         f"run continues (it had sha256 {body.file_sha256}); {needs} needs its "
                         "contents: put that file back")


def listed(body, dim: int) -> Listed:
    """A mesh's or particle file's points (read once per process)."""
    _attached(body, "reading its points")
    if body.shape == "mesh":
        return _mesh(_stamp(body.file), dim, _groups_of(body), int(body.split))
    return _particles(_stamp(body.file), dim, body.step)[0]


def surface(body):
    """A surface body's ``(vertices, triangles, summary)`` (read once per process)."""
    _attached(body, "the surface's inside")
    return _surface(_stamp(body.file))


def bounds(body, dim: int) -> tuple[list, list]:
    """Axis-aligned bounds of a file body: a mesh's nodes, a surface's triangles, the points (a
    detached body's: as recorded; on a parallel run's other ranks: as rank 0 read them)."""
    if recorded_files.detached(body):
        rec = recorded_files.recorded(body)
        return list(rec.lo), list(rec.hi)
    if (rec := recorded_files.shared(body)) is not None:  # rank 0 read it
        return list(rec.lo), list(rec.hi)
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


def listed_volume(body, dim: int) -> float:
    """Total reference volume of a mesh's or particle file's points (the memory and speed checks)."""
    return float(math.fsum(listed(body, dim).vol))


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
