"""What a snapshot holds: the particle fields gathered (in global-id order) for the XDMF series.

One function of the run (a :class:`parmpm.simulation.Simulation`), collective: every rank calls
it, rank 0 gets the fields (None elsewhere) and hands them to the snapshot writer
(:mod:`parmpm.io.xdmf`).
"""
from __future__ import annotations

import numpy as np

from parmpm.measures import axial_stretch


def snapshot_fields(sim) -> dict[str, np.ndarray] | None:
    """The particle fields of one snapshot, gathered on rank 0 (None on the other ranks)."""
    s, P = sim.state, sim.particles
    return sim.gather({"x": P.x, "velocity": P.v, "stress": P.stress.reshape(P.n, s.dim * s.dim),
                       "stretch": axial_stretch(s), "damage": P.damage,
                       "rank": np.full(P.n, float(s.rank)), "gid": P.gid.astype(float)})
