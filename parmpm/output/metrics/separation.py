"""Numerical separation: the connected components of the particle–node graph.

Particles are connected when they share a grid node with nonzero weight (they exchange momentum
through it); the number of connected components of that graph is the number of separated pieces
(Sadeghirad, Brannon & Burghardt 2011 describe separation as particles no longer sharing any
node). The union-find kernel is :func:`parmpm.output.connectivity.local_components`.
"""
from __future__ import annotations

import numpy as np

from parmpm.output.connectivity import compact_nodes, local_components


def count_components(particle_nodes, particle_nnodes, n_nodes) -> int:
    """Number of connected pieces of material (1 = intact, > 1 = numerically separated).

    ``particle_nodes`` is an int array (N, K) of global flat node ids each particle touches with
    nonzero weight, of which the first ``particle_nnodes[p]`` are valid; ``n_nodes`` bounds the
    ids. When ``n_nodes`` is much larger than the number of entries (a big 3D grid), the ids are
    first compressed with ``np.unique`` so memory follows the particles, not the grid.
    """
    particle_nodes = np.ascontiguousarray(particle_nodes, dtype=np.int64)
    particle_nnodes = np.ascontiguousarray(particle_nnodes, dtype=np.int64)
    if particle_nodes.ndim != 2 or particle_nnodes.shape != (particle_nodes.shape[0],):
        raise ValueError("particle_nodes must be (N, K) and particle_nnodes (N,)")
    n = particle_nodes.shape[0]
    if n == 0:
        return 0
    if np.any(particle_nnodes > particle_nodes.shape[1]) or np.any(particle_nnodes < 0):
        raise ValueError("particle_nnodes out of range [0, K]")
    n_nodes = int(n_nodes)
    if n_nodes > 4 * particle_nodes.size + 1024:
        particle_nodes, n_nodes = compact_nodes(particle_nodes, particle_nnodes)
    return int(local_components(particle_nodes, particle_nnodes, max(n_nodes, 1))[0])


__all__ = ["count_components"]
