"""CPDI1 (Sadeghirad, Brannon & Burghardt 2011), dimension-generic.

Domain vectors ``R = [r1 … rd]``; corners ``x_α = x_p + Σ_k s_αk r_k`` with ``s_αk = ±1``;
``V = 2^d det R``. Then ``φ_ip = 2^-d Σ_α S_i(x_α)`` and
``∇φ_ip = (1/V) Σ_α S_i(x_α) cof(R) s_α`` with ``cof(R) = det(R) R^-T`` (2D columns
``(r2y, −r2x)``, ``(−r1y, r1x)``; 3D columns ``r2×r3, r3×r1, r1×r2``). In 1D this is
``(S_i(b) − S_i(a))/(b − a)``. Each corner scatters to its cell's 2^d nodes, so a particle yields
4^d (node, weight, gradient) entries, some for the same node — sums are unaffected.
"""
from parmpm.core.jit import helper_kernel
from parmpm.shapes.hat import hat_axis


@helper_kernel
def cofactor(d, R, C):
    """``C = cof(R) = det(R)·R^-T`` for the leading d×d block (the rest of the 3×3 scratch is
    zeroed); returns det R."""
    for a in range(3):
        for b in range(3):
            C[a, b] = 0.0
    if d == 1:
        C[0, 0] = 1.0
        return R[0, 0]
    if d == 2:
        C[0, 0], C[1, 0], C[0, 1], C[1, 1], det = cofactor_2d(R[0, 0], R[1, 0], R[0, 1], R[1, 1])
        return det
    (C[0, 0], C[1, 0], C[2, 0], C[0, 1], C[1, 1], C[2, 1], C[0, 2], C[1, 2], C[2, 2],
     det) = cofactor_3d(R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1],
                        R[2, 2])
    return det


@helper_kernel
def cofactor_2d(r1x, r1y, r2x, r2y):
    """Cofactor columns ``c1 = (r2y, −r2x)``, ``c2 = (−r1y, r1x)`` and ``det R``:
    ``(c1x, c1y, c2x, c2y, det)``."""
    return r2y, -r2x, -r1y, r1x, r1x * r2y - r2x * r1y


@helper_kernel
def cofactor_3d(R00, R01, R02, R10, R11, R12, R20, R21, R22):
    """Cofactor columns ``c1 = r2×r3``, ``c2 = r3×r1``, ``c3 = r1×r2`` (``r_m`` column ``m − 1``
    of ``R``) and ``det R = r1·c1``: ``(c1x, c1y, c1z, c2x, …, c3z, det)``."""
    c1x, c1y, c1z = R11 * R22 - R21 * R12, R21 * R02 - R01 * R22, R01 * R12 - R11 * R02
    c2x, c2y, c2z = R12 * R20 - R22 * R10, R22 * R00 - R02 * R20, R02 * R10 - R12 * R00
    c3x, c3y, c3z = R10 * R21 - R20 * R11, R20 * R01 - R00 * R21, R00 * R11 - R10 * R01
    return c1x, c1y, c1z, c2x, c2y, c2z, c3x, c3y, c3z, R00 * c1x + R10 * c1y + R20 * c1z


@helper_kernel
def cell_node(d, jk, wk, L0, L1, e):
    """Node ``e`` (``0 … 2^d − 1``, x fastest) of the cell a point lies in, from the per-axis rows
    :func:`parmpm.shapes.hat.hat_axis` filled: its flat index in the box (rows ``L0``, layers
    ``L0·L1`` nodes) and its weight ``S = S_x S_y S_z``. The one walk over a corner's cell
    (CPDI's and cpdi2's entries, cpdi2's corner velocities)."""
    i0 = e & 1
    w1 = wk[1, (e >> 1) & 1] if d > 1 else 1.0
    o1 = jk[1, (e >> 1) & 1] if d > 1 else 0
    w2 = wk[2, e >> 2] if d > 2 else 1.0
    o2 = jk[2, e >> 2] if d > 2 else 0
    return jk[0, i0] + L0 * (o1 + L1 * o2), wk[0, i0] * w1 * w2


@helper_kernel
def cpdi_support(d, xi, R, C, base, nloc, nglob, inv_h, L0, L1, jk, wk, dwk, idx, w, g):
    """(node, weight, gradient) entries of a CPDI particle at grid coordinates ``xi`` with domain
    ``R`` (physical units) and scratch ``C`` for its cofactor. Returns the entry count, or -1 if a
    corner's nodes leave the grid or the patch's local box."""
    det = cofactor(d, R, C)
    ncorner = 1 << d
    inv_v = 1.0 / (ncorner * det)
    wc = 1.0 / ncorner
    n = 0
    for alpha in range(ncorner):
        for k in range(d):
            xk = xi[k]
            for m in range(d):
                sm = 1.0 if (alpha >> m) & 1 else -1.0
                xk += sm * R[k, m] * inv_h[k]
            if hat_axis(xk, base[k], nloc[k], nglob[k], inv_h[k], jk, wk, dwk, k) < 0:
                return -1
        gc0 = gc1 = gc2 = 0.0
        for m in range(d):
            sm = 1.0 if (alpha >> m) & 1 else -1.0
            gc0 += C[0, m] * sm
            gc1 += C[1, m] * sm
            gc2 += C[2, m] * sm
        for e in range(1 << d):
            idx[n], S = cell_node(d, jk, wk, L0, L1, e)
            w[n] = S * wc
            g[n, 0] = S * gc0 * inv_v
            g[n, 1] = S * gc1 * inv_v
            g[n, 2] = S * gc2 * inv_v
            n += 1
    return n
