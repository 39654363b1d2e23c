"""Numerical separation: the connected components of the particle–node graph.

Particles are connected when they share a grid node with nonzero weight (they exchange momentum
through it); the number of connected components of that graph is the number of separated pieces
(Sadeghirad, Brannon & Burghardt 2011 describe separation as particles no longer sharing any
node). The union-find kernel is :func:`parmpm.output.connectivity.local_components`.
"""
from __future__ import annotations

import numpy as np

from parmpm.output.connectivity import local_components


def count_components(particle_nodes, particle_nnodes, n_nodes) -> int:
    """Number of connected pieces of material (1 = intact, > 1 = numerically separated).

    ``particle_nodes`` is an int array (N, K) of global flat node ids each particle touches with
    nonzero weight, of which the first ``particle_nnodes[p]`` are valid; ``n_nodes`` bounds the
    ids. Memory follows the particles, not the grid: the kernel's table holds at most
    ``min(n_nodes, entries)`` ids.
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
    valid = np.arange(particle_nodes.shape[1])[None, :] < particle_nnodes[:, None]
    if np.any(particle_nodes[valid] < 0):
        raise ValueError("particle_nodes holds a negative node id")
    bound = max(1, min(int(n_nodes), int(particle_nnodes.sum())))
    return int(local_components(particle_nodes, particle_nnodes, bound)[0])


__all__ = ["count_components"]
