"""What a particle's domain reaches on the grid: its half-vectors ``r = F r0`` and the box of
nodes near it. Walls (:mod:`parmpm.grid.walls`) and contact (:mod:`parmpm.grid.contact`) both ask
which nodes a particle's domain is near, and how far it reaches along a normal, in the same way."""
import numpy as np

from parmpm.core.jit import helper_kernel


@helper_kernel
def domain_vectors(d, F, r0, i, r):
    """The half-vectors of particle ``i``'s domain into ``r`` (columns): ``F r0``."""
    for a in range(d):
        for j in range(d):
            acc = 0.0
            for b in range(d):
                acc += F[i, a, b] * r0[i, b, j]
            r[a, j] = acc


@helper_kernel
def node_box(d, x, i, r, cells, origin, h, base_p, nloc, lo, hi):
    """Into ``lo``/``hi`` (slot-local node indices, clipped to the slot; axes past ``d`` stay
    0..0): the nodes within the domain's axis extent plus ``cells`` cells of particle ``i``."""
    for a in range(d):
        span = cells * h[a]
        for j in range(d):
            span += abs(r[a, j])
        lo[a] = max(int(np.ceil((x[i, a] - span - origin[a]) / h[a])) - base_p[a], 0)
        hi[a] = min(int(np.floor((x[i, a] + span - origin[a]) / h[a])) - base_p[a], nloc[a] - 1)


@helper_kernel
def half_extent(d, r, n):
    """The domain's half-extent along the unit vector ``n``: ``Σ_j |r_j·n|``."""
    e = 0.0
    for j in range(d):
        rn = 0.0
        for a in range(d):
            rn += r[a, j] * n[a]
        e += abs(rn)
    return e
