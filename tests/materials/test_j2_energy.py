"""The energy ledger of J2 plasticity at one material point, and the hardening laws.

* The plastic work that :func:`parmpm.materials.plasticity.j2.j2_update` returns step by step,
  summed, equals the stress power ``∫ τ:d dt`` per unit reference volume (the trapezoid rule over
  the steps, ``d = sym(Ḟ F⁻¹)`` written here) less the Hencky energy stored in ``b_e`` at the end
  (numpy's eigh, :func:`j2_paths.hencky`), along paths that load, unload and reload:
  ``F(γ) = diag(a, 1, 1)(I + γ e_x⊗e_y)`` with ``γ: 0 → 0.3 → 0.05 → 0.6`` and ``a = 1`` (simple
  shear) or ``a = 1 + γ/2`` (shear and stretch). The gap closes at first order or better as the
  path is refined (the backward-Euler return; the yield onsets fall inside steps, so the measured
  orders scatter over 1.1–2.1); asserted: each doubling shrinks it 1.8× or more, and below
  2.5e-3 of the plastic work at 400 steps per unit γ (measured 1.2–2.0e-3).
* The hardening laws (:mod:`parmpm.materials.plasticity.hardening`) against their formulas
  written again here, their slopes (the Newton tangent) against central differences, and the
  finite slope of ``ε̄p^n`` (``n < 1``) at ``ε̄p = 0``.
* :func:`j2_update` in a compiled particle loop: the same bits as one point at a time.
"""
import math

import numpy as np
import pytest
from j2_paths import LAWS, G, K, Point, hencky, sigma_y

from parmpm.core.jit import kernel, loop_kernel
from parmpm.materials.plasticity.hardening import EPS_FLOOR, yield_stress
from parmpm.materials.plasticity.j2 import j2_update

LEGS = (0.0, 0.3, 0.05, 0.6)
RATE = 1e3  # dγ/dt, for Johnson–Cook's rate term


def F_of(gamma: float, stretch: bool) -> np.ndarray:
    a = 1 + gamma / 2 if stretch else 1.0
    return np.diag([a, 1.0, 1.0]) @ np.array([[1.0, gamma, 0], [0, 1, 0], [0, 0, 1]])


def L_of(gamma: float, stretch: bool) -> np.ndarray:
    """``dF/dγ F⁻¹``: ``diag(a'/a, 0, 0) + a e_x⊗e_y``."""
    a, da = (1 + gamma / 2, 0.5) if stretch else (1.0, 0.0)
    L = np.zeros((3, 3))
    L[0, 0], L[0, 1] = da / a, a
    return L


def ledger(law: str, jit: bool, per_unit: int, stretch: bool):
    """``(Σ plastic work, ∫ τ:d − ψ_end)`` with ``per_unit`` steps per unit of |Δγ|."""
    p, power, g_n = Point(law, jit), 0.0, 0.0
    for g0, g1 in zip(LEGS[:-1], LEGS[1:]):
        n = round(abs(g1 - g0) * per_unit)
        for g in np.linspace(g0, g1, n + 1)[1:]:
            before = np.sum(p.tau * L_of(g_n, stretch))
            p.step(F_of(g, stretch) @ np.linalg.inv(F_of(g_n, stretch)), dt=abs(g - g_n) / RATE)
            power += 0.5 * (before + np.sum(p.tau * L_of(g, stretch))) * (g - g_n)
            g_n = g
    return p.work, power - hencky(p.be)[1]


REFINE = (25, 50, 100, 200, 400)


def ledger_table(law: str, jit: bool, stretch: bool):
    rows = []
    for n in REFINE:
        work, balance = ledger(law, jit, n, stretch)
        rows.append((n, work, abs(work - balance) / work))
    return rows


@pytest.mark.parametrize("jit", [True, False], ids=["jit", "py_func"])
@pytest.mark.parametrize("stretch", [False, True], ids=["shear", "shear+stretch"])
@pytest.mark.parametrize("law", ["linear", "swift", "johnson_cook_rate"])
def test_plastic_work_closes_the_ledger(law, stretch, jit):
    rows = ledger_table(law, jit, stretch)
    gap = np.array([r[2] for r in rows])
    order = np.log2(gap[:-1] / gap[1:])
    assert np.all(order > math.log2(1.8)), rows
    assert gap[-1] < 2.5e-3, rows
    assert rows[-1][1] > 0


@pytest.mark.parametrize("jit", [True, False], ids=["jit", "py_func"])
@pytest.mark.parametrize("law", sorted(LAWS))
def test_hardening_laws(law, jit):
    f = yield_stress if jit else yield_stress.py_func
    code, a, b, n, c, rate0 = LAWS[law]
    for epsp in (0.0, 1e-4, 0.01, 0.3, 2.0):
        for rate in (0.0, 0.5 * rate0, 10 * rate0, 1e4 * rate0):
            sy, h, hr = f(code, a, b, n, c, rate0, epsp, rate)
            assert sy == pytest.approx(sigma_y(law, epsp, rate), rel=1e-14)
            if epsp > 0.0:
                e = 1e-6 * epsp
                fd = (sigma_y(law, epsp + e, rate) - sigma_y(law, epsp - e, rate)) / (2 * e)
                assert h == pytest.approx(fd, rel=1e-6)
            if rate > 0.0 and abs(rate - rate0) > 0.1 * rate0:
                e = 1e-6 * rate
                fd = (sigma_y(law, epsp, rate + e) - sigma_y(law, epsp, rate - e)) / (2 * e)
                assert hr == pytest.approx(fd, rel=1e-6, abs=1e-9 * a)
    if law.startswith("johnson_cook"):  # n < 1: the slope at 0 is finite, the floor's
        h0 = f(code, a, b, n, c, rate0, 0.0, 0.0)[1]
        assert math.isfinite(h0) and h0 == pytest.approx(b * n * EPS_FLOOR ** (n - 1), rel=1e-14)


def test_unknown_code_is_nan():
    assert math.isnan(yield_stress(7, 1.0, 1.0, 1.0, 0.0, 1.0, 0.1, 0.0)[0])


if __name__ == "__main__":  # the ledger table of the docs
    for stretch in (False, True):
        for law in ("linear", "swift", "johnson_cook_rate"):
            print(f"{law}, {'shear+stretch' if stretch else 'shear'}:")
            for n, work, gap in ledger_table(law, True, stretch):
                print(f"  {n:4d} steps/unit γ  plastic work {work:.6e}  |gap|/work = {gap:.3e}")


@loop_kernel
def _update_all(dF, be, epsp, work, tau, hard, dt, M, V, w, t):
    for i in range(be.shape[0]):
        epsp[i], dw = j2_update(dF[i], be[i], epsp[i], K, G, int(hard[0]), hard[1], hard[2],
                                hard[3], hard[4], hard[5], dt, tau[i], M, V, w, t)
        work[i] += dw


@kernel
def update_all(dF, be, epsp, work, tau, hard, dt):
    """A particle loop as the solver will write it: scratch from the ``@kernel`` wrapper, the
    ``@loop_kernel`` (no reference counting) calling the helper on per-particle views."""
    _update_all(dF, be, epsp, work, tau, hard, dt, np.empty((3, 3)), np.empty((3, 3)),
                np.empty(3), np.empty(3))


def test_particle_loop_matches_one_point_at_a_time():
    """:func:`j2_update` compiles inside a ``@loop_kernel`` particle loop (it allocates nothing)
    and gives there, bit for bit, what it gives called on one point."""
    rng = np.random.default_rng(3)
    n = 16
    hard = np.array(LAWS["johnson_cook_rate"], dtype=float)
    dF = np.eye(3) + 0.02 * rng.standard_normal((n, 3, 3))
    be, epsp, work, tau = np.tile(np.eye(3), (n, 1, 1)), np.zeros(n), np.zeros(n), np.zeros((n, 3, 3))
    points = [Point("johnson_cook_rate") for _ in range(n)]
    for _ in range(5):
        update_all(dF, be, epsp, work, tau, hard, 1e-4)
        for i, p in enumerate(points):
            p.step(dF[i], 1e-4)
    assert np.all(epsp > 0)
    for i, p in enumerate(points):
        assert np.array_equal(p.be, be[i]) and np.array_equal(p.tau, tau[i])
        assert p.epsp == epsp[i] and p.work == work[i]
