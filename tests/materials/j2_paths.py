"""Shared by the J2 material-point tests: the material, the hardening laws written again in numpy
(independent of :mod:`parmpm.materials.plasticity.hardening`), one material point driven by
deformation increments, and the test's own Hencky stress from ``b_e`` by ``numpy.linalg.eigh``."""
import math

import numpy as np

from parmpm.materials.plasticity.hardening import JOHNSON_COOK, LINEAR, SWIFT, swift_eps0
from parmpm.materials.plasticity.j2 import j2_update

E, NU = 200e9, 0.3
K, G = E / (3 * (1 - 2 * NU)), E / (2 * (1 + NU))
SY0, H = 250e6, 2e9
#: (code, a, b, n, c, rate0) of each hardening law
LAWS = {
    "linear": (LINEAR, SY0, H, 0.0, 0.0, 1.0),
    "swift": (SWIFT, 600e6, swift_eps0(SY0, 600e6, 0.2), 0.2, 0.0, 1.0),
    "johnson_cook": (JOHNSON_COOK, SY0, 500e6, 0.4, 0.0, 1.0),
    "johnson_cook_rate": (JOHNSON_COOK, SY0, 500e6, 0.4, 0.03, 1.0),
}


def sigma_y(law: str, epsp: float, rate: float = 0.0) -> float:
    """The yield stress as the papers write it."""
    code, a, b, n, c, rate0 = LAWS[law]
    if code == LINEAR:
        return a + b * epsp
    if code == SWIFT:
        return a * (b + epsp) ** n
    return (a + b * epsp ** n) * (1 + c * math.log(max(rate / rate0, 1.0)))


def slope_y(law: str, epsp: float) -> float:
    """dσ_y/dε̄p (rate-free laws), by a central difference."""
    h = 1e-7
    return (sigma_y(law, epsp + h) - sigma_y(law, max(epsp - h, 0.0))) / (epsp + h - max(epsp - h, 0.0))


class Point:
    """One material point: ``b_e``, ``ε̄p``, the Kirchhoff stress and the plastic work so far."""

    def __init__(self, law="linear", jit=True):
        self.law, self.hard = law, LAWS[law]
        self.update = j2_update if jit else j2_update.py_func
        self.be, self.epsp, self.work = np.eye(3), 0.0, 0.0
        self.tau = np.zeros((3, 3))
        self.scratch = (np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3), np.zeros(3))

    def copy(self) -> "Point":
        p = Point.__new__(Point)
        p.law, p.hard, p.update = self.law, self.hard, self.update
        p.be, p.epsp, p.work, p.tau = self.be.copy(), self.epsp, self.work, self.tau.copy()
        p.scratch = self.scratch
        return p

    def step(self, dF: np.ndarray, dt: float = 1.0) -> float:
        epsp, w = self.update(np.ascontiguousarray(dF), self.be, self.epsp, K, G, *self.hard, dt,
                              self.tau, *self.scratch)
        self.epsp, self.work = epsp, self.work + w
        return w


def hencky(be: np.ndarray) -> tuple[np.ndarray, float]:
    """Kirchhoff stress and stored energy of ``b_e`` (numpy's eigh, the test's own law)."""
    lam, n = np.linalg.eigh(be)
    eps = 0.5 * np.log(lam)
    ev = eps.sum()
    dev = eps - ev / 3
    tau = K * ev + 2 * G * dev
    return n @ np.diag(tau) @ n.T, 0.5 * K * ev ** 2 + G * (dev @ dev)


def mises(tau: np.ndarray) -> float:
    s = tau - np.trace(tau) / 3 * np.eye(3)
    return math.sqrt(1.5 * np.sum(s * s))


def solve(f, x0: float, x1: float, tol: float, maxit: int = 60) -> float:
    """A root of ``f`` by the secant method (``f`` piecewise linear or smooth near the root)."""
    f0, f1 = f(x0), f(x1)
    for _ in range(maxit):
        if abs(f1) <= tol or f1 == f0:
            return x1
        x0, x1, f0 = x1, x1 - f1 * (x1 - x0) / (f1 - f0), f1
        f1 = f(x1)
    raise AssertionError(f"no root: f = {f1}")


def bisect(f, lo: float, hi: float, n: int = 200) -> float:
    """A root of ``f`` bracketed by ``[lo, hi]`` (``f(lo) > 0 ≥ f(hi)``)."""
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        if f(mid) > 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
