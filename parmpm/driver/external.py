"""The scene's ``[[loads]]`` made into the stepper's forcing (:mod:`parmpm.loads.external`): which
particles each load acts on, found on every rank at set-up and gathered in global-id order."""
from __future__ import annotations

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.loads.external import (BODY_FORCE, KIND_CODES, POINT, PRESSURE, LoadSet,
                                   surface_faces)
from parmpm.particles.store import Particles
from parmpm.scene.records import SceneSpec


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
            loads.add(code, load.time, load.value, [_nearest(comm, P, load.at)])
        else:
            body = spec.bodies[load.body]
            if body.shape in ("mesh", "particles"):
                raise SceneError(f"loads.{k}: a {load.kind} on body {load.body} (a {body.shape} "
                                 "body) is not supported yet: its particles are not on a lattice, "
                                 "so its surface faces are unknown; use a body_force or point load")
            lo, hi = ranges[load.body]
            mine = np.flatnonzero((P.gid >= lo) & (P.gid < hi))
            try:
                vec, area = surface_faces(d, P.x0[mine], P.r0[mine],
                                          lambda x, b=body: b.inside(d, x),
                                          None if load.region is None else
                                          (load.region.min, load.region.max))
            except SceneError as exc:  # a restart whose surface file is gone: its faces
                raise SceneError(f"loads.{k}: {exc}") from None
            on = area > 0
            parts = comm.allgather((P.gid[mine][on], vec[on], area[on]))
            gids = np.concatenate([p[0] for p in parts])
            if gids.size == 0:
                raise SceneError(f"loads.{k}: the {load.kind} finds no face of body "
                                 f"{load.body}'s surface" + (" inside its region" if load.region
                                                             else ""))
            value = [load.pressure] if code == PRESSURE else load.value
            loads.add(code, load.time, value, gids, np.concatenate([p[1] for p in parts]),
                      np.concatenate([p[2] for p in parts]))
    return loads


def _nearest(comm, P: Particles, at) -> int:
    """The global id of the particle nearest ``at`` at the start (ties: the lowest id)."""
    if P.n:
        dist = np.sum((P.x0 - np.asarray(at, float)) ** 2, axis=1)
        i = int(np.lexsort((P.gid, dist))[0])
        mine = (float(dist[i]), int(P.gid[i]))
    else:
        mine = (np.inf, -1)
    return min(comm.allgather(mine))[1]
