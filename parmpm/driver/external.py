"""The scene's ``[[loads]]`` made into the stepper's forcing (:mod:`parmpm.loads.external`): which
particles each load acts on, found on every rank at set-up and gathered in global-id order.

Rank 0 warns, one line each, where a load is not what the scene likely meant (issue 41): a
traction's or pressure's region that holds surface faces facing more than one way (a region
drawn around a block's face also holds its corner particles' side faces, and the traction acts
on those too: 10 % more force on a 0.4 x 0.2 m block at Δx = 0.02 m), and a point load whose
nearest particle is more than a cell from ``at``. Warnings, not errors: a region around a curved
face holds a staircase of directions by design, and a point load may be meant for a body's
corner; the lines give the numbers to judge by (counts and areas per direction, the distance)."""
from __future__ import annotations

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.core.log import get_logger
from parmpm.loads.external import (BODY_FORCE, KIND_CODES, POINT, PRESSURE, LoadSet,
                                   face_directions, surface_faces)
from parmpm.particles.store import Particles
from parmpm.scene.records import SceneSpec

log = get_logger(__name__)
#: units of a face's area by dimension (a 1D face is a point: its count)
AREA_UNITS = {1: "", 2: " m", 3: " m²"}


def external_loads(spec: SceneSpec, comm, P: Particles, ranges: list,
                   n_total: int) -> LoadSet:
    """The scene's ``[[loads]]`` as a :class:`~parmpm.loads.external.LoadSet` (collective: the
    particles each load acts on are gathered from every rank, in global-id order; ``ranges``:
    every body's global ids ``[first, last)``, as seeded or as the checkpoint records them)."""
    d = spec.dim
    loads = LoadSet(d)
    for k, load in enumerate(spec.loads):
        code = KIND_CODES[load.kind]
        if code == BODY_FORCE:
            lo, hi = ranges[load.body] if load.body is not None else (0, n_total)
            loads.add(code, load.time, load.value, [lo, hi])
        elif code == POINT:
            gid, dist = _nearest(comm, P, load.at)
            if dist > max(spec.grid.cell_size) and comm.Get_rank() == 0:
                log.warning("%s", f"loads.{k}: the point load's nearest particle (id {gid}) is "
                                  f"{dist:.4g} m from at = {_vec(load.at)}, more than a cell "
                                  f"({max(spec.grid.cell_size):g} m): the force acts there")
            loads.add(code, load.time, load.value, [gid])
        else:
            body = spec.bodies[load.body]
            if body.shape in ("mesh", "particles"):
                raise SceneError(f"loads.{k}: a {load.kind} on body {load.body} (a {body.shape} "
                                 "body) is not supported yet: its particles are not on a lattice, "
                                 "so its surface faces are unknown; use a body_force or point load")
            lo, hi = ranges[load.body]
            mine = np.flatnonzero((P.gid >= lo) & (P.gid < hi))
            region = None if load.region is None else (load.region.min, load.region.max)
            try:
                vec, area = surface_faces(d, P.x0[mine], P.r0[mine],
                                          lambda x, b=body: b.inside(d, x), region, load.normal)
                if load.normal is None and (load.region is not None or code != PRESSURE):
                    _warn_directions(comm, k, load, face_directions(
                        d, P.x0[mine], P.r0[mine], lambda x, b=body: b.inside(d, x), region))
            except SceneError as exc:  # a restart whose surface file is gone: its faces
                raise SceneError(f"loads.{k}: {exc}") from None
            on = area > 0
            parts = comm.allgather((P.gid[mine][on], vec[on], area[on]))
            gids = np.concatenate([p[0] for p in parts])
            if gids.size == 0:
                where = (["inside its region"] if load.region is not None else []) + (
                    [f"facing {_vec(load.normal)}"] if load.normal is not None else [])
                raise SceneError(f"loads.{k}: the {load.kind} finds no face of body "
                                 f"{load.body}'s surface" + (" " + " and ".join(where) if where
                                                             else ""))
            value = [load.pressure] if code == PRESSURE else load.value
            loads.add(code, load.time, value, gids, np.concatenate([p[1] for p in parts]),
                      np.concatenate([p[2] for p in parts]))
    return loads


def _nearest(comm, P: Particles, at) -> tuple[int, float]:
    """The global id of the particle nearest ``at`` at the start (ties: the lowest id) and its
    distance."""
    if P.n:
        dist = np.sum((P.x0 - np.asarray(at, float)) ** 2, axis=1)
        i = int(np.lexsort((P.gid, dist))[0])
        mine = (float(dist[i]), int(P.gid[i]))
    else:
        mine = (np.inf, -1)
    d2, gid = min(comm.allgather(mine))
    return gid, float(np.sqrt(d2))


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"


def _direction(u: tuple) -> str:
    """``+x``, ``-y`` for an axis, else the vector."""
    for a, x in enumerate(u):
        if abs(abs(x) - 1.0) < 1e-6:
            return ("+" if x > 0 else "-") + "xyz"[a]
    return _vec(u)


def _warn_directions(comm, k: int, load, local: dict) -> None:
    """One line (rank 0) when the faces a load takes face more than one way (module doc):
    the faces and area per direction, summed over the ranks, and the ``normal`` that would
    keep the largest."""
    total: dict = {}
    for part in comm.allgather(local):
        for u, (n, a) in part.items():
            t = total.setdefault(u, [0, 0.0])
            t[0] += n
            t[1] += a
    if len(total) < 2 or comm.Get_rank() != 0:
        return
    d = len(next(iter(total)))
    order = sorted(total, key=lambda u: (-total[u][1], u))
    counts = ", ".join(f"{total[u][0]} facing {_direction(u)} ({total[u][1]:.4g}{AREA_UNITS[d]})"
                       for u in order)
    best = "[" + ", ".join(f"{x:.6g}" for x in order[0]) + "]"
    where = "region" if load.region is not None else "body's surface"
    log.warning("%s", f"loads.{k}: the {load.kind}'s {where} holds faces facing "
                      f"{len(total)} ways: {counts}; each is loaded (add normal = {best} to "
                      f"load only the faces facing {_direction(order[0])})")
