"""CPDI2 (Sadeghirad, Brannon & Guilkey 2013), dimension-generic: weights of a particle whose
domain is given by its corners, not by ``F`` (derivation and choices: ``docs/cpdi2.md``).

Domain: a segment (1D), quadrilateral (2D) or hexahedron (3D) with corners ``x_α``,
``α = 0 … 2^d − 1``; bit ``m`` of ``α`` gives the sign ``s_αm`` of natural coordinate ``ξ_m``, as
CPDI1's corners ``x_p + Σ_m s_αm r_m`` (:mod:`parmpm.shapes.cpdi`), so an affine domain maps
corner by corner onto CPDI1's. The 2D counter-clockwise tour is ``α = 0, 1, 3, 2``. With the
isoparametric (multi-linear) ``N_α`` on the domain and ``S_i`` the hat of grid node ``i``:

    φ_ip = Σ_α S_i(x_α) wf_α,        wf_α = (1/V) ∫ N_α dV,
    ∇φ_ip = Σ_α S_i(x_α) wg_α,       wg_α = (1/V) ∫ ∇N_α dV = (1/V) ∫ cof(J) ∇_ξN_α dξ,

``J = ∂x/∂ξ``, ``V = ∫ det J dξ``. Both integrands are at most cubic along each ``ξ_m`` (2D:
quadratic), so the 2^d-point Gauss rule (``ξ_m = ±1/√3``, weights 1) is exact.

Domain scaling: every centre-to-corner vector ``c_α = x_α − x_p`` longer than ``l_cr`` is shrunk
to ``l_cr`` (direction kept) before interpolating, so the support stays within ``l_cr`` of the
particle (ghost width ``⌈l_cr / min Δx⌉``, as CPDI1). The tracked corners are never modified.
"""
import math

import numpy as np

from parmpm.core.jit import helper_kernel
from parmpm.shapes.cpdi import cell_node, cofactor_3d
from parmpm.shapes.hat import hat_axis

#: the 2-point Gauss abscissa on [−1, 1] (weight 1)
GAUSS = 1.0 / math.sqrt(3.0)

#: scratch columns: capped corner ``c'_α`` (0‥2), ``wf_α`` (3), ``wg_α`` (4‥6); one row per corner
SCRATCH_SHAPE = (8, 7)
WF, WG = 3, 4

#: return codes of :func:`cpdi2_support` besides the entry count
OUT_OF_BOX, INVERTED = -1, -2


def corner_signs(d: int) -> np.ndarray:
    """``s_αm`` (2^d, d): bit ``m`` of ``α`` set ↔ ``+1`` (the module's corner order)."""
    return np.array([[1.0 if (a >> m) & 1 else -1.0 for m in range(d)] for a in range(1 << d)])


def affine_corners(F: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """The corners ``c_α = F·R0·s_α`` (n, 2^d, d) of the parallelepiped domains ``F·R0`` (CPDI1's
    corners, relative to the particle): CPDI2's corners at seeding. Plain sums, row by row (no
    BLAS), so a particle's corners do not depend on which other particles are in the call."""
    n, d = r0.shape[0], r0.shape[1]
    R = np.zeros((n, d, d))
    for a in range(d):
        for b in range(d):
            for k in range(d):
                R[:, a, b] += F[:, a, k] * r0[:, k, b]
    s = corner_signs(d)
    out = np.zeros((n, 1 << d, d))
    for al in range(1 << d):
        for k in range(d):
            for m in range(d):
                out[:, al, k] += s[al, m] * R[:, k, m]
    return out


@helper_kernel
def cap_corners(d, corners, lcr, out):
    """``out[α, :d] = c_α`` shrunk to length ``lcr`` where ``|c_α| > lcr`` (Homel's domain
    scaling, applied to each corner since a CPDI2 domain has no generating vectors to rebuild).
    A vector within the cap is copied unchanged, so ``lcr = inf`` (``NO_SCALING``) or any cap no
    vector reaches leaves every corner bit for bit. Returns True if any corner was shrunk."""
    changed = False
    for a in range(1 << d):
        nn = 0.0
        for k in range(d):
            nn += corners[a, k] * corners[a, k]
        n = math.sqrt(nn)
        if n > lcr:
            f = lcr / n
            for k in range(d):
                out[a, k] = corners[a, k] * f
            changed = True
        else:
            for k in range(d):
                out[a, k] = corners[a, k]
    return changed


@helper_kernel
def corner_shape(alpha, d, e0, e1, e2):
    """``N_α(ξ) = Π_m (1 + s_αm ξ_m)/2`` and ``∂N_α/∂ξ_m``: ``(N, dN0, dN1, dN2)``. Axes
    ``m ≥ d`` do not exist: factor 1, derivative 0 (so one formula serves 1D, 2D and 3D)."""
    s0 = 1.0 if alpha & 1 else -1.0
    s1 = 1.0 if (alpha >> 1) & 1 else -1.0
    s2 = 1.0 if (alpha >> 2) & 1 else -1.0
    f0 = 0.5 * (1.0 + s0 * e0)
    f1 = 0.5 * (1.0 + s1 * e1) if d > 1 else 1.0
    f2 = 0.5 * (1.0 + s2 * e2) if d > 2 else 1.0
    dn1 = 0.5 * s1 * f0 * f2 if d > 1 else 0.0
    dn2 = 0.5 * s2 * f0 * f1 if d > 2 else 0.0
    return f0 * f1 * f2, 0.5 * s0 * f1 * f2, dn1, dn2


@helper_kernel
def add_point_weights(sc, a, det, cof, shape):
    """One quadrature point's share of corner ``a``'s weight ``∫N_a`` and gradient weight
    ``∫∇N_a`` (``cof``: the columns of ``J``'s cofactor, ``det = det J``; ``shape``:
    ``(N_a, ∂N_a/∂ξ)`` there); shared by the generic and the 3D kernels."""
    k1x, k1y, k1z, k2x, k2y, k2z, k3x, k3y, k3z = cof
    n, g0, g1, g2 = shape
    sc[a, WF] += n * det
    sc[a, WG] += k1x * g0 + k2x * g1 + k3x * g2
    sc[a, WG + 1] += k1y * g0 + k2y * g1 + k3y * g2
    sc[a, WG + 2] += k1z * g0 + k2z * g1 + k3z * g2


@helper_kernel
def normalise_weights(sc, nc, vol):
    """Divide the ``nc`` corners' weights by the domain's volume, when it is positive."""
    if vol > 0.0:
        inv_v = 1.0 / vol
        for a in range(nc):
            for k in range(WF, WG + 3):
                sc[a, k] *= inv_v


@helper_kernel
def domain_weights(d, sc):
    """Fill ``sc[α, WF] = wf_α`` and ``sc[α, WG:WG+3] = wg_α`` (physical units, zero-padded)
    from the corners ``sc[α, :d]`` (relative to any fixed point: ``J`` does not see a
    translation). 2^d-point Gauss quadrature, exact here (module doc); ``J`` is padded with the
    identity on the missing axes so that the 3D cofactor gives the 1D/2D ones. Returns ``V``;
    the weights are only normalised when ``V > 0`` (otherwise the caller reports an inverted
    domain and must not use them)."""
    nc = 1 << d
    for a in range(nc):
        for k in range(WF, WG + 3):
            sc[a, k] = 0.0
    vol = 0.0
    for q in range(nc):
        e0 = GAUSS if q & 1 else -GAUSS
        e1 = GAUSS if (q >> 1) & 1 else -GAUSS
        e2 = GAUSS if (q >> 2) & 1 else -GAUSS
        J00 = J01 = J02 = J10 = J11 = J12 = J20 = J21 = J22 = 0.0
        for a in range(nc):
            _, g0, g1, g2 = corner_shape(a, d, e0, e1, e2)
            c0 = sc[a, 0]
            c1 = sc[a, 1] if d > 1 else 0.0
            c2 = sc[a, 2] if d > 2 else 0.0
            J00 += c0 * g0
            J01 += c0 * g1
            J02 += c0 * g2
            J10 += c1 * g0
            J11 += c1 * g1
            J12 += c1 * g2
            J20 += c2 * g0
            J21 += c2 * g1
            J22 += c2 * g2
        if d < 2:
            J11 = 1.0
        if d < 3:
            J22 = 1.0
        (k1x, k1y, k1z, k2x, k2y, k2z, k3x, k3y, k3z,
         det) = cofactor_3d(J00, J01, J02, J10, J11, J12, J20, J21, J22)
        vol += det
        for a in range(nc):
            add_point_weights(sc, a, det, (k1x, k1y, k1z, k2x, k2y, k2z, k3x, k3y, k3z),
                              corner_shape(a, d, e0, e1, e2))
    normalise_weights(sc, nc, vol)
    return vol


@helper_kernel
def cpdi2_support(d, xi, corners, lcr, base, nloc, nglob, inv_h, L0, L1, jk, wk, dwk, idx, w, g,
                  scratch):
    """(node, weight, gradient) entries of a CPDI2 particle at grid coordinates ``xi`` whose
    domain has the corners ``x_p + corners[α]`` (``corners`` (2^d, d), physical units, bit order
    of the module doc), capped at ``lcr`` first (``inf``: no scaling). ``scratch``: float64, at
    least :data:`SCRATCH_SHAPE` (capped corners and ``wf``, ``wg``, left there for the caller).

    Each corner scatters ``S_i(x'_α)·(wf_α, wg_α)`` to the 2^d nodes of its cell: 4^d entries,
    nodes repeating (sums are unaffected), the layout of CPDI1's. Returns the entry count;
    ``INVERTED`` (-2) if the (capped) domain's volume is not positive or is NaN — checked first, so
    the caller can raise "domain of particle N inverted"; ``OUT_OF_BOX`` (-1) if a corner's nodes
    leave the grid or the patch's local box."""
    cap_corners(d, corners, lcr, scratch)
    vol = domain_weights(d, scratch)
    if not vol > 0.0:
        return INVERTED
    n = 0
    for alpha in range(1 << d):
        for k in range(d):
            xk = xi[k] + scratch[alpha, k] * inv_h[k]
            if hat_axis(xk, base[k], nloc[k], nglob[k], inv_h[k], jk, wk, dwk, k) < 0:
                return OUT_OF_BOX
        wf = scratch[alpha, WF]
        gc0 = scratch[alpha, WG]
        gc1 = scratch[alpha, WG + 1]
        gc2 = scratch[alpha, WG + 2]
        for e in range(1 << d):
            idx[n], S = cell_node(d, jk, wk, L0, L1, e)
            w[n] = S * wf
            g[n, 0] = S * gc0
            g[n, 1] = S * gc1
            g[n, 2] = S * gc2
            n += 1
    return n
