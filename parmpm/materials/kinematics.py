"""Kinematics of one particle, written once for every kernel: ``det F``, ``b = F Fᵀ``, the
Gershgorin bound of ``b``'s largest eigenvalue and the update ``F ← (I + Δt L) F``.

Each quantity comes in the forms the kernels need side by side: a dimension-generic one on the
leading d×d block of 3×3 arrays (:mod:`parmpm.transfer.generic`) and scalar 2D/3D ones on the entries
(:mod:`parmpm.transfer.kernels2d`, :mod:`parmpm.transfer.kernels3d`). Where two forms group a sum differently
(the F update) each keeps its own grouping, so every kernel's results stay what they were bit
for bit; the tests hold the forms to each other.
"""
from parmpm.core.jit import helper_kernel


@helper_kernel
def det_d(d, F):
    """``det F`` of the leading d×d block."""
    if d == 1:
        return F[0, 0]
    if d == 2:
        return det_2d(F[0, 0], F[0, 1], F[1, 0], F[1, 1])
    return det_3d(F[0, 0], F[0, 1], F[0, 2], F[1, 0], F[1, 1], F[1, 2], F[2, 0], F[2, 1], F[2, 2])


@helper_kernel
def det_2d(f00, f01, f10, f11):
    return f00 * f11 - f01 * f10


@helper_kernel
def det_3d(f00, f01, f02, f10, f11, f12, f20, f21, f22):
    return (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
            + f02 * (f10 * f21 - f11 * f20))


@helper_kernel
def left_cauchy_green_2d(f00, f01, f10, f11):
    """``b = F Fᵀ`` as ``(b00, b01, b11)``."""
    return f00 * f00 + f01 * f01, f00 * f10 + f01 * f11, f10 * f10 + f11 * f11


@helper_kernel
def left_cauchy_green_3d(f00, f01, f02, f10, f11, f12, f20, f21, f22):
    """``b = F Fᵀ`` as ``(b00, b01, b02, b11, b12, b22)``."""
    return (f00 * f00 + f01 * f01 + f02 * f02, f00 * f10 + f01 * f11 + f02 * f12,
            f00 * f20 + f01 * f21 + f02 * f22, f10 * f10 + f11 * f11 + f12 * f12,
            f10 * f20 + f11 * f21 + f12 * f22, f20 * f20 + f21 * f21 + f22 * f22)


@helper_kernel
def gershgorin_bound(d, F):
    """``max_a Σ_b |b_ab|`` of ``b = F Fᵀ`` (leading d×d block): an upper bound of the largest
    eigenvalue, exact in 1D."""
    bmax = 0.0
    for a in range(d):
        row = 0.0
        for b in range(d):
            bab = 0.0
            for k in range(d):
                bab += F[a, k] * F[b, k]
            row += abs(bab)
        bmax = max(bmax, row)
    return bmax


@helper_kernel
def gershgorin_2d(b00, b01, b11):
    """:func:`gershgorin_bound` from the entries of ``b``."""
    return max(abs(b00) + abs(b01), abs(b01) + abs(b11))


@helper_kernel
def gershgorin_3d(b00, b01, b02, b11, b12, b22):
    """:func:`gershgorin_bound` from the entries of ``b``."""
    a01, a02, a12 = abs(b01), abs(b02), abs(b12)
    return max(abs(b00) + a01 + a02, a01 + abs(b11) + a12, a02 + a12 + abs(b22))


@helper_kernel
def update_F(d, dt, L, F, Fn):
    """``F ← F + Δt L F`` in place on the leading d×d block (``Fn``: 3×3 scratch)."""
    for a in range(d):
        for b in range(d):
            s = F[a, b]
            for k in range(d):
                s += dt * L[a, k] * F[k, b]
            Fn[a, b] = s
    for a in range(d):
        for b in range(d):
            F[a, b] = Fn[a, b]


@helper_kernel
def update_F_2d(l00, l01, l10, l11, f00, f01, f10, f11):
    """The entries of ``F + l F`` with ``l = Δt L``."""
    return (f00 + (l00 * f00 + l01 * f10), f01 + (l00 * f01 + l01 * f11),
            f10 + (l10 * f00 + l11 * f10), f11 + (l10 * f01 + l11 * f11))


@helper_kernel
def update_F_3d(l00, l01, l02, l10, l11, l12, l20, l21, l22,
                f00, f01, f02, f10, f11, f12, f20, f21, f22):
    """The entries of ``F + l F`` with ``l = Δt L``."""
    return (f00 + (l00 * f00 + l01 * f10 + l02 * f20), f01 + (l00 * f01 + l01 * f11 + l02 * f21),
            f02 + (l00 * f02 + l01 * f12 + l02 * f22), f10 + (l10 * f00 + l11 * f10 + l12 * f20),
            f11 + (l10 * f01 + l11 * f11 + l12 * f21), f12 + (l10 * f02 + l11 * f12 + l12 * f22),
            f20 + (l20 * f00 + l21 * f10 + l22 * f20), f21 + (l20 * f01 + l21 * f11 + l22 * f21),
            f22 + (l20 * f02 + l21 * f12 + l22 * f22))


@helper_kernel
def flip_pic(flip, vp, dv, vg):
    """The particle's new velocity component: ``α (v_p + Δv) + (1 − α) v`` with ``Δv`` and ``v``
    interpolated from the grid (``α = 1``: FLIP, ``α = 0``: PIC)."""
    return flip * (vp + dv) + (1.0 - flip) * vg
