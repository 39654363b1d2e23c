"""Logarithm and exponential of a symmetric 3×3 matrix near the identity, by series, for the
plastic pass's J2 update of metals, whose elastic stretches stay within a few per cent of 1.

Why beside the eigen-solvers: a metal's ``b_e`` is ``I + X`` with ``‖X‖`` of the order of its
yield strain, and Hencky's J2 needs only ``ln b_e`` and, after a return, ``exp`` of the returned
log strain — matrix functions, not the principal axes. A series in ``X`` is a fixed chain of
products of commuting symmetric matrices: no square roots, trigonometry or branches, so particles
overlap in the pipeline, where the closed-form eigen-solve is one long chain of dependent roots
and divisions (165 of a particle's 245 ns in the pass, measured).

* ``ln(I + X) = 2 artanh Z = 2 (Z + Z³/3 + Z⁵/5 + …)``, ``Z = X (2I + X)⁻¹``: an eigenvalue ``x``
  of ``X`` becomes ``x/(2 + x)``, so for ``‖X‖₂ ≤ ρ`` the series runs in ``z ≤ ρ/(2 − ρ)`` and its
  terms fall by ``z²``. With :data:`RHO_MAX` = 0.1 (``z² ≤ 2.8e-3``) the terms through ``Z¹³``
  leave a truncation below ``z¹⁴/15 ≈ 1e-19`` of the result.
* ``exp D = Σ Dᵏ/k!`` through ``D¹²``: for ``‖D‖₂ ≤ 0.25`` the first term left out
  is below ``0.25¹³/13! ≈ 2e-18`` of the result.

Matrices are six scalars in :data:`parmpm.materials.plasticity.state.SYM`'s order
``(00, 11, 22, 01, 02, 12)``; a product is formed as ``A B`` with ``A``'s rows, which for
commuting ``A``, ``B`` (polynomials in one matrix) is symmetric up to round-off.
``tests/materials/test_near_identity.py`` holds both to extended-precision Taylor sums and to
the eigen-decomposition.
"""
import math

from parmpm.core.jit import helper_kernel

#: the largest Frobenius norm of ``X = b − I`` the series serve (``‖X‖₂ ≤ ‖X‖_F``)
RHO_MAX = 0.1
#: artanh terms ``Z^(2k+1)/(2k+1)``, k = 0 … 6: the coefficients ``1/(2k+1)``
C1, C2, C3, C4, C5, C6 = 1.0 / 3.0, 1.0 / 5.0, 1.0 / 7.0, 1.0 / 9.0, 1.0 / 11.0, 1.0 / 13.0
#: exponential terms ``D^k/k!``, k = 0 … EXP_ORDER (a multiple of 4)
EXP_ORDER = 12
#: ``1/k!``, k = 0 … EXP_ORDER
INV_FACTORIAL = tuple(1.0 / math.factorial(k) for k in range(EXP_ORDER + 1))


@helper_kernel
def sym_product(a00, a11, a22, a01, a02, a12, b00, b11, b22, b01, b02, b12):
    """``A B`` of two commuting symmetric matrices, as six scalars."""
    return (a00 * b00 + a01 * b01 + a02 * b02,
            a01 * b01 + a11 * b11 + a12 * b12,
            a02 * b02 + a12 * b12 + a22 * b22,
            a00 * b01 + a01 * b11 + a02 * b12,
            a00 * b02 + a01 * b12 + a02 * b22,
            a01 * b02 + a11 * b12 + a12 * b22)


@helper_kernel
def square_and_cube(a00, a11, a22, a01, a02, a12):
    """``(A², A A²)`` of a symmetric ``A``, as twelve scalars."""
    b00, b11, b22, b01, b02, b12 = sym_product(a00, a11, a22, a01, a02, a12,
                                               a00, a11, a22, a01, a02, a12)
    return (b00, b11, b22, b01, b02, b12) + sym_product(a00, a11, a22, a01, a02, a12,
                                                        b00, b11, b22, b01, b02, b12)


@helper_kernel
def sym_combination(c0, c1, a00, a11, a22, a01, a02, a12, c2, b00, b11, b22, b01, b02, b12, c3,
                    d00, d11, d22, d01, d02, d12):
    """``c0 I + c1 A + c2 B + c3 D`` of symmetric matrices, as six scalars, summed left to
    right."""
    return (c0 + c1 * a00 + c2 * b00 + c3 * d00, c0 + c1 * a11 + c2 * b11 + c3 * d11,
            c0 + c1 * a22 + c2 * b22 + c3 * d22, c1 * a01 + c2 * b01 + c3 * d01,
            c1 * a02 + c2 * b02 + c3 * d02, c1 * a12 + c2 * b12 + c3 * d12)


@helper_kernel
def log_near_identity(x00, x11, x22, x01, x02, x12):
    """``ln(I + X)`` for a symmetric ``X`` with ``‖X‖_F ≤`` :data:`RHO_MAX`, as six scalars."""
    y00, y11, y22 = 2.0 + x00, 2.0 + x11, 2.0 + x22  # Y = 2I + X; its inverse by cofactors
    c00, c11, c22 = y11 * y22 - x12 * x12, y00 * y22 - x02 * x02, y00 * y11 - x01 * x01
    c01, c02, c12 = x02 * x12 - x01 * y22, x01 * x12 - x02 * y11, x01 * x02 - y00 * x12
    idet = 1.0 / (y00 * c00 + x01 * c01 + x02 * c02)
    z00, z11, z22, z01, z02, z12 = sym_product(x00, x11, x22, x01, x02, x12, c00 * idet,
                                               c11 * idet, c22 * idet, c01 * idet, c02 * idet,
                                               c12 * idet)
    # P(Q) = Σ_{k<7} Q^k/(2k+1), Q = Z², as B0 + Q³ B1 (Paterson & Stockmeyer 1973: three
    # products after Q where Horner's rule chains six), then ln(I + X) = 2 Z P
    q00, q11, q22, q01, q02, q12 = sym_product(z00, z11, z22, z01, z02, z12,
                                               z00, z11, z22, z01, z02, z12)
    (r00, r11, r22, r01, r02, r12,
     s00, s11, s22, s01, s02, s12) = square_and_cube(q00, q11, q22, q01, q02, q12)
    b00, b11, b22, b01, b02, b12 = sym_combination(C3, C4, q00, q11, q22, q01, q02, q12,
                                                   C5, r00, r11, r22, r01, r02, r12,
                                                   C6, s00, s11, s22, s01, s02, s12)
    p00, p11, p22, p01, p02, p12 = sym_product(s00, s11, s22, s01, s02, s12,
                                               b00, b11, b22, b01, b02, b12)
    p00, p11, p22, p01, p02, p12 = sym_combination(1.0, C1, q00, q11, q22, q01, q02, q12,
                                                   C2, r00, r11, r22, r01, r02, r12,
                                                   1.0, p00, p11, p22, p01, p02, p12)
    l00, l11, l22, l01, l02, l12 = sym_product(z00, z11, z22, z01, z02, z12,
                                               p00, p11, p22, p01, p02, p12)
    return 2.0 * l00, 2.0 * l11, 2.0 * l22, 2.0 * l01, 2.0 * l02, 2.0 * l12


@helper_kernel
def exp_near_zero(d00, d11, d22, d01, d02, d12):
    """``exp D`` for a symmetric ``D`` with ``‖D‖₂ ≤ 0.25``, as six scalars: ``Σ_{k≤12} Dᵏ/k!``
    as ``A0 + D⁴ (A1 + D⁴ (A2 + D⁴ A3))``, each ``A_j`` a combination of ``I, D, D², D³``
    (Paterson & Stockmeyer 1973: six products where Horner's rule chains twelve)."""
    (e00, e11, e22, e01, e02, e12,
     f00, f11, f22, f01, f02, f12) = square_and_cube(d00, d11, d22, d01, d02, d12)
    g00, g11, g22, g01, g02, g12 = sym_product(e00, e11, e22, e01, e02, e12,
                                               e00, e11, e22, e01, e02, e12)
    h = INV_FACTORIAL[EXP_ORDER]  # the innermost block, A3 = I/12!
    p00, p11, p22, p01, p02, p12 = h, h, h, 0.0, 0.0, 0.0
    for j in range(EXP_ORDER // 4 - 1, -1, -1):
        p00, p11, p22, p01, p02, p12 = sym_product(g00, g11, g22, g01, g02, g12,
                                                   p00, p11, p22, p01, p02, p12)
        # A_j but for its multiple of I, which is added last, where it rounds least
        a00, a11, a22, a01, a02, a12 = sym_combination(
            0.0, INV_FACTORIAL[4 * j + 1], d00, d11, d22, d01, d02, d12,
            INV_FACTORIAL[4 * j + 2], e00, e11, e22, e01, e02, e12,
            INV_FACTORIAL[4 * j + 3], f00, f11, f22, f01, f02, f12)
        a0 = INV_FACTORIAL[4 * j]
        p00, p11, p22, p01, p02, p12 = ((p00 + a00) + a0, (p11 + a11) + a0, (p22 + a22) + a0,
                                        p01 + a01, p02 + a02, p12 + a12)
    return p00, p11, p22, p01, p02, p12
