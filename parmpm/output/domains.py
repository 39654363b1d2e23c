"""Particle domains as the interpolation sees them: corners and sizes (analysis and figures).

Each interpolator gives a particle a domain (its characteristic function is what the weights
average over):

* ``cpdi``: the parallelogram/parallelepiped ``x_p + R ξ``, ``ξ ∈ [−1, 1]^d``, ``R = F·R0`` then
  capped at ``l_cr`` (:func:`parmpm.shapes.scaling.scale_domain`);
* ``cpdi2``: the (multi-linear) domain of its tracked corners ``x_p + c_α``, each capped at
  ``l_cr`` (:func:`parmpm.shapes.cpdi2.cap_corners`): the functions below take the particles'
  ``corners`` field;
* ``cpgimp``: the axis-aligned box of half-widths ``l0_k·|F_kk|`` (collapses when the material
  turns by 90°: ``F_kk = cos θ``);
* ``ugimp``: the fixed box of half-widths ``l0_k``;
* ``mpm`` and ``bspline``: a point (weights of the centre alone); its *nominal* box of half-widths
  ``l0_k`` is returned, for drawing only.

Domain "size" is the length (1D), area (2D) or volume (3D): ``2^d |det R|``, ``Π 2 l_k`` or, for
cpdi2, the (capped) domain's ``V = ∫ det J dξ``.
In 1D with USL the CPDI domains tile the bar (docs/verification.md §4), so the sizes sum to its length.
Not on the time-step path.
"""
from __future__ import annotations

import numpy as np

from parmpm.core.jit import kernel
from parmpm.core.records import kernel_lcr
from parmpm.shapes import CPDI, CPDI2, CPGIMP
from parmpm.shapes.cpdi2 import SCRATCH_SHAPE, cap_corners, corner_signs, domain_weights
from parmpm.shapes.support import domain_matrix

__all__ = ["domain_vectors", "domain_corners", "domain_sizes", "capped_corners"]


@kernel
def _vectors(d, method, lcr, F, r0, lh0, out):
    R = np.zeros((3, 3))
    for i in range(F.shape[0]):
        if method == CPDI:
            domain_matrix(d, method, lcr, F[i], r0[i], R)
            for a in range(d):
                for b in range(d):
                    out[i, a, b] = R[a, b]
        else:
            for a in range(d):
                for b in range(d):
                    out[i, a, b] = 0.0
                half = lh0[i, a]
                if method == CPGIMP:
                    half *= abs(F[i, a, a])
                out[i, a, a] = half


@kernel
def _capped(d, lcr, corners, out, size):
    """``out[i]``: the corners of particle ``i`` capped at ``lcr``; ``size[i]`` its domain's
    ``V`` (:func:`parmpm.shapes.cpdi2.domain_weights`)."""
    sc = np.zeros(SCRATCH_SHAPE)
    for i in range(corners.shape[0]):
        cap_corners(d, corners[i], lcr, sc)
        for a in range(1 << d):
            for k in range(d):
                out[i, a, k] = sc[a, k]
        size[i] = domain_weights(d, sc)


def capped_corners(dim: int, lcr: float | None, corners) -> tuple[np.ndarray, np.ndarray]:
    """cpdi2: ((N, 2^d, d) corners capped at ``lcr``, relative to the particle, in the bit order
    of :mod:`parmpm.shapes.cpdi2`; (N,) the volumes they enclose)."""
    if corners is None:
        raise ValueError("cpdi2 domains are the particles' corners: pass corners=")
    corners = np.ascontiguousarray(corners, float)
    out = np.zeros(corners.shape)
    size = np.zeros(corners.shape[0])
    _capped(dim, kernel_lcr(lcr), corners, out, size)
    return out, size


def domain_vectors(dim: int, method: int, lcr: float | None, F, r0, lh0,
                   corners=None) -> np.ndarray:
    """(N, d, d) centre-to-face vectors (columns) of every particle's domain; for cpdi2 the
    parallelepiped closest to its capped corners, ``R = 2^-d Σ_α ĉ_α ⊗ s_α`` (exactly its domain
    while that is one)."""
    if method == CPDI2:
        c, _ = capped_corners(dim, lcr, corners)
        return np.einsum("nak,am->nkm", c, corner_signs(dim)) / (1 << dim)
    n = np.shape(F)[0]
    out = np.zeros((n, dim, dim))
    _vectors(dim, method, kernel_lcr(lcr), np.ascontiguousarray(F, float),
             np.ascontiguousarray(r0, float), np.ascontiguousarray(lh0, float), out)
    return out


def domain_corners(dim: int, method: int, lcr: float, x, F, r0, lh0, corners=None) -> np.ndarray:
    """Corners of every domain, in order around it: (N, 2, 1) in 1D, (N, 4, 2) in 2D and the
    (N, 8, 3) box corners in 3D (axis 0 fastest); cpdi2: its capped tracked ``corners``."""
    if method == CPDI2:
        c, _ = capped_corners(dim, lcr, corners)
        if dim == 2:  # bit order → around the quadrilateral (counter-clockwise when V > 0)
            c = c[:, [0, 1, 3, 2]]
        return np.asarray(x, float)[:, None, :] + c
    R = domain_vectors(dim, method, lcr, F, r0, lh0)
    if dim == 2:
        signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    else:
        grids = np.meshgrid(*([[-1.0, 1.0]] * dim), indexing="ij")
        signs = np.stack([g.ravel() for g in grids[::-1]], axis=1)
    return np.asarray(x, float)[:, None, :] + np.einsum("nab,cb->nca", R, signs)


def domain_sizes(dim: int, method: int, lcr: float, F, r0, lh0, corners=None) -> np.ndarray:
    """Length / area / volume of every domain: ``2^d |det R|`` (cpdi2: ``V`` of its capped
    ``corners``)."""
    if method == CPDI2:
        return capped_corners(dim, lcr, corners)[1]
    R = domain_vectors(dim, method, lcr, F, r0, lh0)
    return (2.0 ** dim) * np.abs(np.linalg.det(R))
