"""Eigen-decomposition of a symmetric 3×3 matrix, for the return maps' principal axes of ``b_e``.

Cyclic Jacobi rotations (Golub & Van Loan, *Matrix Computations*, §8.5; the rotation of Numerical
Recipes §11.1): each rotation zeroes one off-diagonal entry and every sweep shrinks the off-diagonal
norm quadratically, so a few sweeps reach round-off. Unlike the closed-form (Cardano) roots,
Jacobi keeps its accuracy when eigenvalues repeat — the common case here: a body at rest has
``b_e = I``, a hydrostatic one ``α² I``, plane strain and 1D a block-diagonal ``b_e`` — and the
eigenvectors it returns are orthonormal to round-off even then, because they are a product of
rotations. The matrix is held in six scalars, so nothing is allocated and the input is left as is.
"""
import math

from parmpm.core.jit import helper_kernel

#: sweeps at most; a 3×3 converges in 4–6
MAX_SWEEPS = 50


@helper_kernel
def jacobi_rotation(app, aqq, apq):
    """``(t, c, s)`` of the Jacobi rotation that zeroes ``a_pq``: ``t = tan θ`` the smaller root
    of ``t² + 2ϑt − 1 = 0``, ``ϑ = (a_qq − a_pp)/(2 a_pq)`` (``t ≈ 1/(2ϑ)`` where ``ϑ²``
    would overflow)."""
    theta = (aqq - app) / (2.0 * apq)
    if abs(theta) > 1.0e150:
        t = 0.5 / theta
    else:
        t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
        if theta < 0.0:
            t = -t
    c = 1.0 / math.sqrt(t * t + 1.0)
    return t, c, t * c


@helper_kernel
def _rotate_columns(V, p, q, c, s):
    """``V ← V J(p, q, θ)``: the rotation accumulated into the eigenvector columns."""
    for k in range(3):
        vp, vq = V[k, p], V[k, q]
        V[k, p] = c * vp - s * vq
        V[k, q] = s * vp + c * vq


@helper_kernel
def sym_eig3(A, w, V):
    """Eigenvalues ``w`` (3,), ascending, and orthonormal eigenvectors, the columns of ``V``
    (3, 3), of the symmetric ``A`` (3, 3; its upper triangle is read, it is not changed):
    ``A = V diag(w) Vᵀ``. Returns the number of sweeps (``MAX_SWEEPS + 1``: not converged)."""
    a00, a01, a02 = A[0, 0], A[0, 1], A[0, 2]
    a11, a12, a22 = A[1, 1], A[1, 2], A[2, 2]
    for i in range(3):
        for j in range(3):
            V[i, j] = 1.0 if i == j else 0.0
    sweeps = 0
    while True:
        off = a01 * a01 + a02 * a02 + a12 * a12
        scale = a00 * a00 + a11 * a11 + a22 * a22 + 2.0 * off
        # converged when the off-diagonal part is below round-off of the whole matrix
        if off <= 1.0e-36 * scale or off == 0.0:
            break
        if sweeps == MAX_SWEEPS:
            sweeps += 1
            break
        sweeps += 1
        if a01 != 0.0:  # (p, q, r) = (0, 1, 2)
            t, c, s = jacobi_rotation(a00, a11, a01)
            a00, a11 = a00 - t * a01, a11 + t * a01
            a02, a12 = c * a02 - s * a12, s * a02 + c * a12
            a01 = 0.0
            _rotate_columns(V, 0, 1, c, s)
        if a02 != 0.0:  # (0, 2, 1)
            t, c, s = jacobi_rotation(a00, a22, a02)
            a00, a22 = a00 - t * a02, a22 + t * a02
            a01, a12 = c * a01 - s * a12, s * a01 + c * a12
            a02 = 0.0
            _rotate_columns(V, 0, 2, c, s)
        if a12 != 0.0:  # (1, 2, 0)
            t, c, s = jacobi_rotation(a11, a22, a12)
            a11, a22 = a11 - t * a12, a22 + t * a12
            a01, a02 = c * a01 - s * a02, s * a01 + c * a02
            a12 = 0.0
            _rotate_columns(V, 1, 2, c, s)
    w[0], w[1], w[2] = a00, a11, a22
    # ascending order by three compare-and-swaps (eigenvector columns follow)
    for p, q in ((0, 1), (1, 2), (0, 1)):
        if w[q] < w[p]:
            w[p], w[q] = w[q], w[p]
            for k in range(3):
                V[k, p], V[k, q] = V[k, q], V[k, p]
    return sweeps


@helper_kernel
def from_principal(w, V, out):
    """``out = Σ_A w_A v_A v_Aᵀ`` (3, 3) from principal values ``w`` (3,) and the eigenvector
    columns of ``V``."""
    for i in range(3):
        for j in range(i, 3):
            x = w[0] * V[i, 0] * V[j, 0] + w[1] * V[i, 1] * V[j, 1] + w[2] * V[i, 2] * V[j, 2]
            out[i, j] = x
            out[j, i] = x


@helper_kernel
def trial_log_strains(dF, be, M, V, w):
    """The return maps' elastic predictor: ``M = ΔF b_e ΔFᵀ`` (3, 3), its eigenvectors ``V`` and
    principal log strains ``w = ½ ln λ`` (NaN for a non-positive ``λ``)."""
    for i in range(3):
        for j in range(i, 3):
            x = 0.0
            for k in range(3):
                fik = dF[i, k]
                for m in range(3):
                    x += fik * be[k, m] * dF[j, m]
            M[i, j] = x
            M[j, i] = x
    sym_eig3(M, w, V)
    for A in range(3):
        w[A] = 0.5 * math.log(w[A]) if w[A] > 0.0 else math.nan
