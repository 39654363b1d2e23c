"""Eigen-decomposition of a symmetric 3×3 matrix in closed form, for the plastic pass: the
trigonometric roots of the deviator's characteristic cubic and eigenvectors by cross products,
after D. Eberly (2014), *A Robust Eigensolver for 3 × 3 Symmetric Matrices* (Geometric Tools).

Why beside :mod:`.spectral`'s Jacobi: Jacobi's ten or so rotations, each a chain of square roots
and divisions, took 320 of the 380 ns of a particle's elastic step in the plastic pass; this
takes about a third of that. It stays accurate where eigenvalues repeat, which Cardano's roots
of the matrix itself do not:

* the roots are those of the deviator ``B = A − (tr A/3) I`` scaled to unit size, so ``b_e`` near
  the identity (every particle at rest, every elastic metal) loses nothing to the shift;
* the root farthest from the other two (the largest when the cubic's ``det/2 ≥ 0``, else the
  smallest) is accurate even where the other two meet, and so is its eigenvector, the longest
  cross product of two rows of ``B − β I``; its eigenvalue is then its Rayleigh quotient;
* the other two come from ``B``'s 2×2 block in the plane orthogonal to that vector, diagonalised
  by one Jacobi rotation: exact for a double root, where the trigonometric roots lose half their
  digits (``acos`` near ±1); the basis is orthonormal to round-off whatever the spectrum.

``tests/materials/test_spectral.py`` holds it to Jacobi's bounds (eigenvalues and the rebuilt
matrix to 1e-14 of its norm, the basis orthonormal to 1e-14) on random, near-identity (to 1e-15
absolute) and repeated spectra.
"""
import math

from parmpm.core.jit import helper_kernel
from parmpm.materials.plasticity.spectral import jacobi_rotation

TWO_PI_3 = 2.0 * math.pi / 3.0


@helper_kernel
def _first_vector(b00, b01, b02, b11, b12, b22, beta, V, col):
    """Unit null vector of ``B − β I`` (β an isolated root) into column ``col`` of ``V``: the
    longest cross product of its rows."""
    r00, r11, r22 = b00 - beta, b11 - beta, b22 - beta
    # rows (r00, b01, b02), (b01, r11, b12), (b02, b12, r22)
    x0, y0, z0 = b01 * b12 - b02 * r11, b02 * b01 - r00 * b12, r00 * r11 - b01 * b01
    x1, y1, z1 = b01 * r22 - b02 * b12, b02 * b02 - r00 * r22, r00 * b12 - b01 * b02
    x2, y2, z2 = r11 * r22 - b12 * b12, b12 * b02 - b01 * r22, b01 * b12 - r11 * b02
    d0 = x0 * x0 + y0 * y0 + z0 * z0
    d1 = x1 * x1 + y1 * y1 + z1 * z1
    d2 = x2 * x2 + y2 * y2 + z2 * z2
    if d0 >= d1 and d0 >= d2:
        x, y, z, dd = x0, y0, z0, d0
    elif d1 >= d2:
        x, y, z, dd = x1, y1, z1, d1
    else:
        x, y, z, dd = x2, y2, z2, d2
    inv = 1.0 / math.sqrt(dd)
    V[0, col], V[1, col], V[2, col] = x * inv, y * inv, z * inv


@helper_kernel
def _plane_pair(b00, b01, b02, b11, b12, b22, V, first, lo, hi):
    """The two eigenpairs of ``B`` in the plane orthogonal to column ``first`` of ``V``: ``B``'s
    2×2 block in an orthonormal basis ``(U, S)`` of that plane, diagonalised by one Jacobi
    rotation (exact, whatever the two roots: the trigonometric roots lose half their digits at
    a double root, this does not use them); the vectors into columns ``lo`` and ``hi`` (the
    smaller root first); returns the two roots."""
    w0, w1, w2 = V[0, first], V[1, first], V[2, first]
    if abs(w0) > abs(w1):  # U ⟂ W, then S = W × U
        inv = 1.0 / math.sqrt(w0 * w0 + w2 * w2)
        u0, u1, u2 = -w2 * inv, 0.0, w0 * inv
    else:
        inv = 1.0 / math.sqrt(w1 * w1 + w2 * w2)
        u0, u1, u2 = 0.0, w2 * inv, -w1 * inv
    s0, s1, s2 = w1 * u2 - w2 * u1, w2 * u0 - w0 * u2, w0 * u1 - w1 * u0
    bs0 = b00 * s0 + b01 * s1 + b02 * s2
    bs1 = b01 * s0 + b11 * s1 + b12 * s2
    bs2 = b02 * s0 + b12 * s1 + b22 * s2
    m00 = (u0 * (b00 * u0 + b01 * u1 + b02 * u2) + u1 * (b01 * u0 + b11 * u1 + b12 * u2)
           + u2 * (b02 * u0 + b12 * u1 + b22 * u2))
    m01 = u0 * bs0 + u1 * bs1 + u2 * bs2
    m11 = s0 * bs0 + s1 * bs1 + s2 * bs2
    c, s = 1.0, 0.0
    if m01 != 0.0:  # the rotation zeroing m01
        t, c, s = jacobi_rotation(m00, m11, m01)
        m00, m11 = m00 - t * m01, m11 + t * m01
    # eigenvectors: c U − s S (root m00) and s U + c S (root m11)
    a0, a1, a2 = c * u0 - s * s0, c * u1 - s * s1, c * u2 - s * s2
    z0, z1, z2 = s * u0 + c * s0, s * u1 + c * s1, s * u2 + c * s2
    if m11 < m00:
        m00, m11 = m11, m00
        a0, a1, a2, z0, z1, z2 = z0, z1, z2, a0, a1, a2
    V[0, lo], V[1, lo], V[2, lo] = a0, a1, a2
    V[0, hi], V[1, hi], V[2, hi] = z0, z1, z2
    return m00, m11


@helper_kernel
def sym_eig3_closed(A, w, V):
    """Eigenvalues ``w`` (3,), ascending, and orthonormal eigenvectors, the columns of ``V``
    (3, 3), of the symmetric ``A`` (3, 3; its upper triangle is read): ``A = V diag(w) Vᵀ``, as
    :func:`parmpm.materials.plasticity.spectral.sym_eig3` gives them. NaN in, NaN out."""
    q = (A[0, 0] + A[1, 1] + A[2, 2]) / 3.0
    b00, b11, b22 = A[0, 0] - q, A[1, 1] - q, A[2, 2] - q
    b01, b02, b12 = A[0, 1], A[0, 2], A[1, 2]
    scale = max(abs(b00), abs(b11), abs(b22), abs(b01), abs(b02), abs(b12))
    if not scale > 0.0:  # a multiple of I (or NaN: the multiple is NaN)
        nan = q + b01 + b02 + b12 + scale  # NaN if any entry is
        for i in range(3):
            w[i] = nan
            for j in range(3):
                V[i, j] = 1.0 if i == j else 0.0
        return
    inv = 1.0 / scale
    b00, b11, b22, b01, b02, b12 = b00 * inv, b11 * inv, b22 * inv, b01 * inv, b02 * inv, b12 * inv
    p = math.sqrt((b00 * b00 + b11 * b11 + b22 * b22
                   + 2.0 * (b01 * b01 + b02 * b02 + b12 * b12)) / 6.0)
    ip = 1.0 / p
    c00, c11, c22, c01, c02, c12 = b00 * ip, b11 * ip, b22 * ip, b01 * ip, b02 * ip, b12 * ip
    half_det = 0.5 * (c00 * (c11 * c22 - c12 * c12) - c01 * (c01 * c22 - c12 * c02)
                      + c02 * (c01 * c12 - c11 * c02))
    half_det = min(max(half_det, -1.0), 1.0)
    phi = math.acos(half_det) / 3.0
    # the isolated root: the largest (2 cos φ) for half_det ≥ 0, else the smallest; it is
    # accurate even where the other two meet (its slope in φ vanishes there)
    if half_det >= 0.0:
        iso, lo, hi = 2, 0, 1
        beta = 2.0 * math.cos(phi)
    else:
        iso, lo, hi = 0, 1, 2
        beta = 2.0 * math.cos(phi + TWO_PI_3)
    r = p * beta
    _first_vector(b00, b01, b02, b11, b12, b22, r, V, iso)
    x0, x1, x2 = V[0, iso], V[1, iso], V[2, iso]
    r = (x0 * (b00 * x0 + b01 * x1 + b02 * x2) + x1 * (b01 * x0 + b11 * x1 + b12 * x2)
         + x2 * (b02 * x0 + b12 * x1 + b22 * x2))  # its Rayleigh quotient
    ra, rb = _plane_pair(b00, b01, b02, b11, b12, b22, V, iso, lo, hi)
    w[iso], w[lo], w[hi] = q + scale * r, q + scale * ra, q + scale * rb
    for a, b in ((0, 1), (1, 2), (0, 1)):  # ascending (the isolated root may tie a pair's)
        if w[b] < w[a]:
            w[a], w[b] = w[b], w[a]
            for k in range(3):
                V[k, a], V[k, b] = V[k, b], V[k, a]
