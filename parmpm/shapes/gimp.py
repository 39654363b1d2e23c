"""GIMP weights per axis for a top-hat particle of any half-width (uGIMP and cpGIMP).

Bardenhagen & Kober (2004): ``φ_i = (1/2l) ∫_{x_p−l}^{x_p+l} S_i(x) dx`` and
``∇φ_i = (1/2l) ∫ ∇S_i dx = (S_i(x_p+l) − S_i(x_p−l)) / 2l``. With the hat's antiderivative
``Φ`` (in grid units) this is ``φ_j = (Φ(ξ+l−j) − Φ(ξ−l−j)) / 2l`` — exact for every ``l``, so
cpGIMP domains that stretch beyond half a cell stay correct (the usual piecewise-quadratic
closed form assumes ``l ≤ Δx/2``). uGIMP keeps ``l = Δx/(2·ppc)``; cpGIMP uses
``l_k = l0_k·|F_kk|``, the common choice whose failure under large rotation the studies show.
"""
import math

from parmpm.jit import kernel
from parmpm.shapes.hat import SNAP


@kernel
def _hat(s):
    a = abs(s)
    return 1.0 - a if a < 1.0 else 0.0


@kernel
def _hat_integral(s):
    """Φ(s) = ∫_{-∞}^{s} max(0, 1 − |t|) dt."""
    if s <= -1.0:
        return 0.0
    if s < 0.0:
        return 0.5 * (s + 1.0) * (s + 1.0)
    if s < 1.0:
        return 1.0 - 0.5 * (1.0 - s) * (1.0 - s)
    return 1.0


@kernel
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
    inv2l = 0.5 / half
    for t in range(n):
        j = lo + t
        jk[a, t] = j - base
        wk[a, t] = (_hat_integral(xi + half - j) - _hat_integral(xi - half - j)) * inv2l
        dwk[a, t] = (_hat(xi + half - j) - _hat(xi - half - j)) * inv2l * inv_h
    return n
