"""Particle domains as the interpolation sees them: corners and sizes (analysis and figures).

Each interpolator gives a particle a domain (its characteristic function is what the weights
average over):

* ``cpdi``: the parallelogram/parallelepiped ``x_p + R ξ``, ``ξ ∈ [−1, 1]^d``, ``R = F·R0`` then
  capped at ``l_cr`` (:func:`parmpm.shapes.scaling.scale_domain`);
* ``cpgimp``: the axis-aligned box of half-widths ``l0_k·|F_kk|`` (collapses when the material
  turns by 90°: ``F_kk = cos θ``);
* ``ugimp``: the fixed box of half-widths ``l0_k``;
* ``mpm`` and ``bspline``: a point (weights of the centre alone); its *nominal* box of half-widths
  ``l0_k`` is returned, for drawing only.

Domain "size" is the length (1D), area (2D) or volume (3D): ``2^d |det R|`` or ``Π 2 l_k``.
In 1D with USL the CPDI domains tile the bar (docs/verification.md §4), so the sizes sum to its length.
Not on the time-step path.
"""
from __future__ import annotations

import numpy as np

from parmpm.jit import kernel
from parmpm.kernel_records import kernel_lcr
from parmpm.shapes import CPDI, CPGIMP
from parmpm.shapes.support import domain_matrix

__all__ = ["domain_vectors", "domain_corners", "domain_sizes"]


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


def domain_vectors(dim: int, method: int, lcr: float | None, F, r0, lh0) -> np.ndarray:
    """(N, d, d) centre-to-face vectors (columns) of every particle's domain."""
    n = np.shape(F)[0]
    out = np.zeros((n, dim, dim))
    _vectors(dim, method, kernel_lcr(lcr), np.ascontiguousarray(F, float),
             np.ascontiguousarray(r0, float), np.ascontiguousarray(lh0, float), out)
    return out


def domain_corners(dim: int, method: int, lcr: float, x, F, r0, lh0) -> np.ndarray:
    """Corners of every domain, in order around it: (N, 2, 1) in 1D, (N, 4, 2) in 2D and the
    (N, 8, 3) box corners in 3D (axis 0 fastest)."""
    R = domain_vectors(dim, method, lcr, F, r0, lh0)
    if dim == 2:
        signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    else:
        grids = np.meshgrid(*([[-1.0, 1.0]] * dim), indexing="ij")
        signs = np.stack([g.ravel() for g in grids[::-1]], axis=1)
    return np.asarray(x, float)[:, None, :] + np.einsum("nab,cb->nca", R, signs)


def domain_sizes(dim: int, method: int, lcr: float, F, r0, lh0) -> np.ndarray:
    """Length / area / volume of every domain: ``2^d |det R|``."""
    R = domain_vectors(dim, method, lcr, F, r0, lh0)
    return (2.0 ** dim) * np.abs(np.linalg.det(R))
