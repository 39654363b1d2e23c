"""CPDI domain scaling (Homel, MPM workshop 2013): cap every center-to-corner vector at ``l_cr``.

2D: ``l_a = r1 + r2``, ``l_b = r1 − r2``; each longer than ``l_cr`` is shrunk to ``l_cr``; then
``r1' = (l_a' + l_b')/2``, ``r2' = (l_a' − l_b')/2`` (exact: the new corners are ``±l_a', ±l_b'``).
3D: ``l_a = r1+r2+r3``, ``l_b = r1−r2+r3``, ``l_c = −r1+r2+r3``, ``l_d = −r1−r2+r3``, shrink, then
the seed's pseudo-inverse rebuild ``r1' = (l_a+l_b−l_c−l_d)/4``, ``r2' = (l_a−l_b+l_c−l_d)/4``,
``r3' = (l_a+l_b+l_c+l_d)/4``. Four shrunk vectors need not span a parallelepiped, so the rebuilt
corners can overshoot ``l_cr`` (by up to 50 %); we recompute them and, if the longest still exceeds
``l_cr``, scale all of ``R'`` uniformly by ``l_cr/max|corner|`` so the ghost-width bound holds.
1D: clamp the half-length ``|r1|`` to ``l_cr``.
``R'`` is used for interpolation only; the material ``F``, volume and stress are untouched.
When no vector exceeds ``l_cr``, ``R`` is returned unchanged (bit for bit).
"""
import math

from parmpm.core.jit import helper_kernel


@helper_kernel
def _norm(v0, v1, v2):
    return math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)


@helper_kernel
def scale_domain(d, R, lcr):
    """Scale the domain vectors (columns of the 3×3 array ``R``, first ``d`` used) in place so no
    center-to-corner vector is longer than ``lcr``. Returns True if anything changed."""
    if d == 1:
        if abs(R[0, 0]) > lcr:
            R[0, 0] = lcr if R[0, 0] > 0 else -lcr
            return True
        return False
    if d == 2:
        r1x, r1y, r2x, r2y, changed = cap_2d(lcr, R[0, 0], R[1, 0], R[0, 1], R[1, 1])
        R[0, 0], R[1, 0], R[0, 1], R[1, 1] = r1x, r1y, r2x, r2y
        return changed
    R00, R01, R02, R10, R11, R12, R20, R21, R22, changed = cap_3d(
        lcr, R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1], R[2, 2])
    R[0, 0], R[0, 1], R[0, 2] = R00, R01, R02
    R[1, 0], R[1, 1], R[1, 2] = R10, R11, R12
    R[2, 0], R[2, 1], R[2, 2] = R20, R21, R22
    return changed


@helper_kernel
def cap_2d(lcr, r1x, r1y, r2x, r2y):
    """The 2D cap on the entries of ``r1``, ``r2``: ``(r1x, r1y, r2x, r2y, changed)``."""
    la0, la1 = r1x + r2x, r1y + r2y
    lb0, lb1 = r1x - r2x, r1y - r2y
    na, nb = math.sqrt(la0 * la0 + la1 * la1), math.sqrt(lb0 * lb0 + lb1 * lb1)
    if na <= lcr and nb <= lcr:
        return r1x, r1y, r2x, r2y, False
    if na > lcr:
        la0, la1 = la0 * (lcr / na), la1 * (lcr / na)
    if nb > lcr:
        lb0, lb1 = lb0 * (lcr / nb), lb1 * (lcr / nb)
    return 0.5 * (la0 + lb0), 0.5 * (la1 + lb1), 0.5 * (la0 - lb0), 0.5 * (la1 - lb1), True


@helper_kernel
def cap_3d(lcr, R00, R01, R02, R10, R11, R12, R20, R21, R22):
    """The 3D cap on the entries of ``R`` (column ``m`` is ``r_{m+1}``): the nine entries and
    whether anything changed."""
    # the four center-to-corner vectors (the other four are their negatives)
    a0, a1, a2, ca = _cap(R00 + R01 + R02, R10 + R11 + R12, R20 + R21 + R22, lcr)
    b0, b1, b2, cb = _cap(R00 - R01 + R02, R10 - R11 + R12, R20 - R21 + R22, lcr)
    c0, c1, c2, cc = _cap(-R00 + R01 + R02, -R10 + R11 + R12, -R20 + R21 + R22, lcr)
    e0, e1, e2, ce = _cap(-R00 - R01 + R02, -R10 - R11 + R12, -R20 - R21 + R22, lcr)
    if not (ca or cb or cc or ce):
        return R00, R01, R02, R10, R11, R12, R20, R21, R22, False
    R00, R10, R20 = 0.25 * (a0 + b0 - c0 - e0), 0.25 * (a1 + b1 - c1 - e1), 0.25 * (a2 + b2 - c2 - e2)
    R01, R11, R21 = 0.25 * (a0 - b0 + c0 - e0), 0.25 * (a1 - b1 + c1 - e1), 0.25 * (a2 - b2 + c2 - e2)
    R02, R12, R22 = 0.25 * (a0 + b0 + c0 + e0), 0.25 * (a1 + b1 + c1 + e1), 0.25 * (a2 + b2 + c2 + e2)
    longest = max(_norm(R00 + R01 + R02, R10 + R11 + R12, R20 + R21 + R22),
                  _norm(-R00 + R01 + R02, -R10 + R11 + R12, -R20 + R21 + R22),
                  _norm(R00 - R01 + R02, R10 - R11 + R12, R20 - R21 + R22),
                  _norm(-R00 - R01 + R02, -R10 - R11 + R12, -R20 - R21 + R22))
    f = lcr / longest
    if f < 1.0:
        R00, R01, R02 = R00 * f, R01 * f, R02 * f
        R10, R11, R12 = R10 * f, R11 * f, R12 * f
        R20, R21, R22 = R20 * f, R21 * f, R22 * f
    return R00, R01, R02, R10, R11, R12, R20, R21, R22, True


@helper_kernel
def longest_corner(d, R):
    """Length of the longest center-to-corner vector ``|Σ_k s_k r_k|`` of the domain ``R``."""
    longest = 0.0
    for alpha in range(1 << (d - 1)):
        v0 = v1 = v2 = 0.0
        for m in range(d):
            s = -1.0 if (m < d - 1 and (alpha >> m) & 1) else 1.0
            v0 += s * R[0, m]
            v1 += s * R[1, m]
            v2 += s * R[2, m]
        longest = max(longest, _norm(v0, v1, v2))
    return longest


@helper_kernel
def _cap(v0, v1, v2, lcr):
    n = _norm(v0, v1, v2)
    if n > lcr:
        f = lcr / n
        return v0 * f, v1 * f, v2 * f, True
    return v0, v1, v2, False
