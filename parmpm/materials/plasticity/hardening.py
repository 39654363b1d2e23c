"""Isotropic hardening: the yield stress ``σ_y(ε̄p, ε̄̇p)`` and its slopes, for the return maps.

One function over the laws by code, the constants as scalars ``(a, b, n, c, rate0)`` read per law:

* ``LINEAR``: ``σ_y = a + b ε̄p`` (``a = σ_y0``, ``b = H``; ``H = 0``: perfect plasticity);
* ``SWIFT`` (Swift 1952, *J. Mech. Phys. Solids* 1, 1–18): ``σ_y = a (b + ε̄p)^n`` (``a = A``,
  ``b = ε0 > 0``; :func:`swift_eps0` gives the ``ε0`` of a wanted initial yield stress);
* ``JOHNSON_COOK`` (Johnson & Cook 1983, *Proc. 7th Int. Symp. Ballistics*, 541–547), without the
  thermal factor: ``σ_y = (a + b ε̄p^n)(1 + c ln max(ε̄̇p/rate0, 1))`` (``a = A``, ``b = B``,
  ``c = C``; ``c = 0`` turns the rate term off).

``ε̄p^n`` with ``n < 1`` has an infinite slope at ``ε̄p = 0`` (Johnson–Cook from a virgin state; a
Swift law given ``ε0 = 0``). The slope is taken at ``max(ε̄p, EPS_FLOOR)`` instead, a finite and
very steep tangent: the stress itself is exact, and the return map's Newton iteration
(:mod:`.j2`), safeguarded by bisection, converges from the left on the concave curve whatever
the tangent. The rate term's slope ``c σ_s/ε̄̇p`` is zero below ``rate0`` (the ``max`` clips it).
"""
import math

from parmpm.core.jit import helper_kernel

LINEAR, SWIFT, JOHNSON_COOK = 0, 1, 2
#: hardening law name → code
HARDENING = {"linear": LINEAR, "swift": SWIFT, "johnson_cook": JOHNSON_COOK}
#: the smallest ε̄p at which a power law's slope ``n ε̄p^(n−1)`` is evaluated
EPS_FLOOR = 1.0e-12


def swift_eps0(sigma_y0: float, A: float, n: float) -> float:
    """``ε0`` of the Swift law whose initial yield stress ``A ε0^n`` is ``sigma_y0``."""
    return (sigma_y0 / A) ** (1.0 / n)


@helper_kernel
def _power_slope(x, n):
    """``d(x^n)/dx`` at ``max(x, EPS_FLOOR)`` (finite for ``n < 1``)."""
    return n * max(x, EPS_FLOOR) ** (n - 1.0)


@helper_kernel
def yield_stress(code, a, b, n, c, rate0, epsp, rate):
    """``(σ_y, ∂σ_y/∂ε̄p, ∂σ_y/∂ε̄̇p)`` at equivalent plastic strain ``epsp`` and rate ``rate``
    (NaN for an unknown code)."""
    if code == LINEAR:
        return a + b * epsp, b, 0.0
    if code == SWIFT:
        return a * (b + epsp) ** n, a * _power_slope(b + epsp, n), 0.0
    if code == JOHNSON_COOK:
        static = a + b * epsp ** n
        dstatic = b * _power_slope(epsp, n)
        if c != 0.0 and rate > rate0:
            factor = 1.0 + c * math.log(rate / rate0)
            return static * factor, dstatic * factor, static * c / rate
        return static, dstatic, 0.0
    return math.nan, math.nan, 0.0
