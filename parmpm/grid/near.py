"""What a particle's domain reaches on the grid: its half-vectors ``r = F r0``, the box of
nodes near it and where a line through a node crosses it. Walls (:mod:`parmpm.grid.walls`) and contact (:mod:`parmpm.grid.contact`) both ask
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


@helper_kernel
def line_span(d, r, q, n, inv):
    """``(t_lo, t_hi)``: the stretch ``node + t n`` of the line through a node along the unit
    ``n`` that lies in a particle's domain ``x_p + r a``, ``|a_j| ≤ 1`` (``r``: its half-vectors
    in columns, ``q = x_p − node``); ``t_lo > t_hi`` where the line misses it (or the domain is
    flat). With ``a = r⁻¹ (t n − q)`` every ``|a_j| ≤ 1`` is an interval of ``t`` (the slab
    test); ``inv``: (3, 3) scratch for ``r⁻¹``."""
    if d == 1:
        det = r[0, 0]
        if det != 0.0:
            inv[0, 0] = 1.0 / det
    elif d == 2:
        det = r[0, 0] * r[1, 1] - r[0, 1] * r[1, 0]
        if det != 0.0:
            inv[0, 0], inv[0, 1] = r[1, 1] / det, -r[0, 1] / det
            inv[1, 0], inv[1, 1] = -r[1, 0] / det, r[0, 0] / det
    else:
        m0 = r[1, 1] * r[2, 2] - r[1, 2] * r[2, 1]
        m1 = r[1, 2] * r[2, 0] - r[1, 0] * r[2, 2]
        m2 = r[1, 0] * r[2, 1] - r[1, 1] * r[2, 0]
        det = r[0, 0] * m0 + r[0, 1] * m1 + r[0, 2] * m2
        if det != 0.0:
            inv[0, 0] = m0 / det
            inv[0, 1] = (r[0, 2] * r[2, 1] - r[0, 1] * r[2, 2]) / det
            inv[0, 2] = (r[0, 1] * r[1, 2] - r[0, 2] * r[1, 1]) / det
            inv[1, 0] = m1 / det
            inv[1, 1] = (r[0, 0] * r[2, 2] - r[0, 2] * r[2, 0]) / det
            inv[1, 2] = (r[0, 2] * r[1, 0] - r[0, 0] * r[1, 2]) / det
            inv[2, 0] = m2 / det
            inv[2, 1] = (r[0, 1] * r[2, 0] - r[0, 0] * r[2, 1]) / det
            inv[2, 2] = (r[0, 0] * r[1, 1] - r[0, 1] * r[1, 0]) / det
    if det == 0.0:
        return 1.0, -1.0
    lo = -np.inf
    hi = np.inf
    for j in range(d):
        u = 0.0
        w = 0.0
        for a in range(d):
            u += inv[j, a] * q[a]
            w += inv[j, a] * n[a]
        if w == 0.0:  # the line parallel to this pair of faces: inside them or not at all
            if abs(u) > 1.0:
                return 1.0, -1.0
            continue
        t1 = (u - 1.0) / w
        t2 = (u + 1.0) / w
        lo = max(lo, min(t1, t2))
        hi = min(hi, max(t1, t2))
    return lo, hi
