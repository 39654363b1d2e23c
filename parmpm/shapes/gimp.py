"""GIMP weights per axis for a top-hat particle of any half-width (uGIMP and cpGIMP).

Bardenhagen & Kober (2004): ``φ_i = (1/2l) ∫_{x_p−l}^{x_p+l} S_i(x) dx`` and
``∇φ_i = (1/2l) ∫ ∇S_i dx = (S_i(x_p+l) − S_i(x_p−l)) / 2l``, evaluated piecewise between the
hat's kinks so it is exact for every ``l`` — including a collapsed domain (``l → 0``, cpGIMP at 90°
rotation), where it becomes the hat at the centre — so
cpGIMP domains that stretch beyond half a cell stay correct (the usual piecewise-quadratic
closed form assumes ``l ≤ Δx/2``). uGIMP keeps ``l = Δx/(2·ppc)``; cpGIMP uses
``l_k = l0_k·|F_kk|``, the common choice whose failure under large rotation the studies show.
"""
import math

from parmpm.core.jit import helper_kernel
from parmpm.shapes.hat import SNAP


@helper_kernel
def _hat(s):
    a = abs(s)
    return 1.0 - a if a < 1.0 else 0.0


@helper_kernel
def _hat_average(a, b):
    """Mean of the hat over [a, b] (node-relative grid units), split at its kinks -1, 0, 1 so each
    piece is linear and integrates exactly as length × midpoint value: no cancellation when the
    domain is thin (a collapsed cpGIMP domain averages to the hat at its centre)."""
    if b <= a:
        return _hat(a)
    total = 0.0
    lo = a
    for k in (-1.0, 0.0, 1.0, math.inf):
        if k <= lo:
            continue
        hi = min(k, b)
        total += (hi - lo) * _hat(0.5 * (lo + hi))
        lo = hi
        if lo >= b:
            break
    return total / (b - a)


@helper_kernel
def _hat_slope_average(a, b):
    """Mean of the hat's derivative over [a, b]: ``(S(b) − S(a))/(b − a)``, or the slope of the
    piece when the domain is degenerate or lies within one linear piece."""
    if b <= a or math.floor(a) == math.floor(b):
        m = 0.5 * (a + b)
        if m <= -1.0 or m >= 1.0:
            return 0.0
        return 1.0 if m < 0.0 else -1.0
    return (_hat(b) - _hat(a)) / (b - a)


@helper_kernel
def gimp_axis(xi, half, base, nloc, nglob, inv_h, jk, wk, dwk, a):
    """Row ``a`` of (jk, wk, dwk): nodes, weights and gradients along one axis for a top-hat of
    half-width ``half`` (grid units) centred at ``xi``. Returns the node count, or -1 if the
    support leaves the grid or the patch's local box (or exceeds the row length)."""
    lo = int(math.floor(xi - half))
    hi = int(math.ceil(xi + half))  # node hi+1's hat ends where the domain does
    if hi > nglob - 1 and xi + half - (nglob - 1) < SNAP:
        hi = nglob - 1  # round-off past the grid's far face
    if lo < 0 and xi - half > -SNAP:
        lo = 0
    if lo < 0 or hi > nglob - 1 or lo - base < 0 or hi - base > nloc - 1:
        return -1
    n = hi - lo + 1
    if n > jk.shape[1]:
        return -1
    for t in range(n):
        j = lo + t
        jk[a, t] = j - base
        wk[a, t] = _hat_average(xi - half - j, xi + half - j)
        dwk[a, t] = _hat_slope_average(xi - half - j, xi + half - j) * inv_h
    return n
