"""Drucker–Prager's volume correction (``volume_correction = true``; Tampubolon et al. 2017):
the volume a particle gained plastically comes back free of stress under compression, and the
skeleton is loaded only once the particle is denser than it started.

Checked through the plastic pass (:func:`parmpm.materials.plasticity.update.plastic_pass`, both
its series and its eigen path) against

* closed forms on a hydrostatic cycle in 3D: stress-free while ``J > 1``, then Hencky's
  ``τ = K ln J I``, with no plastic volume left and the stored energy ``½ K (ln J)²``;
* an independent model written here for the other paths: ``b_e`` updated by increments (not the
  pass's ``C_p⁻¹``) and Tampubolon et al.'s scalar accumulator ``v`` (not the pass's
  ``ln J − tr ε*``), ``ε* + v/3 I`` handed to the return map;

and the energy ledger: every step's plastic work ≥ 0, and on the cycle the total tends to 0
(first order in the step) as the stored energy ``½ K (ln J)²`` is all the stress power did.
"""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from parmpm.materials.plasticity.drucker_prager import dp_return
from parmpm.materials.plasticity.state import STATE_WORK, initial_state, plastic_volume
from parmpm.materials.plasticity.table import (PCOL_COHESION, PCOL_ETA, PCOL_ETA_BAR, PCOL_G,
                                               PCOL_K, PCOL_PT, PCOL_VOLUME_CORRECTION, PCOL_XI,
                                               plastic_table)
from parmpm.materials.plasticity.update import plastic_energy_sums, plastic_pass

NONE = dict(hardening_exponent=None, strength_coefficient=None, rate_coefficient=None,
            reference_rate=None, yield_stress=None, hardening=None, hardening_modulus=None,
            matching=None, tension_cutoff=None, friction_angle_2=None)
#: Bui et al. (2008)'s rods: cohesionless, no dilatancy
RODS = SimpleNamespace(**NONE, model="drucker_prager", youngs_modulus=8.4e5, poisson_ratio=0.3,
                       density=2650.0, friction_angle=19.8, dilatancy_angle=0.0, cohesion=0.0,
                       volume_correction=True)
#: cohesive and dilatant: the correction gives back the cut-off's and the cone's volume alike
COHESIVE = SimpleNamespace(**{**vars(RODS), "youngs_modulus": 5e7, "friction_angle": 30.0,
                              "dilatancy_angle": 10.0, "cohesion": 1e4})


def table_of(material, correction=True):
    return plastic_table({"m": SimpleNamespace(**{**vars(material),
                                                  "volume_correction": correction})}, ["m"])


def run_pass(table, d, path):
    """The pass along ``path`` (d×d deformation gradients): per step (stress, state row, the
    pass's ``ln J_p``)."""
    F = np.eye(d)[None].copy()
    state, stress = initial_state(1), np.zeros((1, d, d))
    mat, v = np.zeros(1, np.int64), np.zeros((1, d))
    out = []
    for Fd in path:
        F[0] = Fd
        plastic_pass(d, F, mat, table, state, stress, v, 1e-4)
        out.append((stress[0].copy(), state[0].copy(), plastic_volume(state)[0]))
    return out


def hydrostatic(d, J_values):
    """``F = J^(1/d) I``: in 3D a hydrostatic path; in plane strain and 1D the same volumes
    with ``F_zz`` (and ``F_yy``) held at 1."""
    return [np.eye(d) * J ** (1.0 / d) for J in J_values]


def cycle(steps):
    """Dilate to J = 2, compact back to J = 1.3 (still loose), then to J = 0.9 (denser than the
    start): ``steps`` increments in each leg."""
    return np.concatenate([np.linspace(1.0, 2.0, steps + 1)[1:], np.linspace(2.0, 1.3, steps + 1)[1:],
                           np.linspace(1.3, 0.9, steps + 1)[1:]])


@pytest.mark.parametrize("steps", [1, 40])
def test_loose_grains_compact_free_of_stress_then_press_as_hencky(steps):
    """3D hydrostatic cycle: at J = 2 and back at J = 1.3 no stress (without the correction
    J = 1.3 would already press at ``K ln(1.3/2)``); at J = 0.9 the Cauchy stress is
    ``K ln J / J I``, the plastic volume is 0 and the stored energy ``½ K (ln J)²``. One step a
    leg takes the eigen path (``b_e^tr`` far from I), 40 the series path."""
    table = table_of(RODS)
    K = table[0, PCOL_K]
    Js = cycle(steps)
    rows = run_pass(table, 3, hydrostatic(3, Js))
    at = {round(J, 12): r for J, r in zip(Js, rows)}
    for J in (2.0, 1.3):
        np.testing.assert_allclose(at[J][0], 0.0, atol=1e-12 * K)
        assert at[J][2] == pytest.approx(math.log(J), abs=1e-12)
    sig, state, lnJp = at[0.9]
    np.testing.assert_allclose(sig, K * math.log(0.9) / 0.9 * np.eye(3), rtol=1e-12)
    assert abs(lnJp) < 1e-12
    F = np.eye(3)[None] * 0.9 ** (1.0 / 3.0)
    stored = plastic_energy_sums(3, np.array([0, 1]), np.zeros(1, np.uint64), np.ones(1), F,
                                 np.zeros(1, np.int64), table, state[None])[0, 0]
    assert stored == pytest.approx(0.5 * K * math.log(0.9) ** 2, rel=1e-10)
    # the model without the correction keeps the dilated volume as its new reference
    plain = run_pass(table_of(RODS, correction=False), 3, hydrostatic(3, Js))
    sig13 = plain[2 * steps - 1][0]  # the end of the second leg (J = 1.3 is on the first too)
    np.testing.assert_allclose(sig13, K * math.log(1.3 / 2.0) / 1.3 * np.eye(3), rtol=1e-10)


@pytest.mark.parametrize("steps", [10, 30, 90])
def test_the_cycles_plastic_work_is_the_crossing_steps(steps):
    """On the 3D cycle only the step that crosses J = 1 does plastic work: it takes back the last
    free volume ``ln J_n`` under its new pressure ``K ln J_{n+1}``, so ``W_p = −K ln J_{n+1} ln
    J_n`` (≥ 0), second order in the step — the discrete scheme's own ledger, which tends to
    the exact cycle's (stress power ``∫ K ln J d(ln J)`` over ``J < 1`` only: all of it stored).
    Every other step's work is 0 and ``W_p`` never decreases."""
    Js = cycle(steps)
    rows = run_pass(table_of(RODS), 3, hydrostatic(3, Js))
    K = table_of(RODS)[0, PCOL_K]
    works = np.array([r[1][STATE_WORK] for r in rows])
    k = int(np.argmax(Js < 1.0))  # the crossing step
    assert np.all(works[:k] == 0.0) and np.all(works[k:] == works[k])
    assert works[-1] == pytest.approx(-K * math.log(Js[k]) * math.log(Js[k - 1]), rel=1e-9)
    assert works[-1] == pytest.approx(K * (0.2 / steps) ** 2, rel=0.02)  # J = 1 mid-step


def reference(table, d, path):
    """The independent model: ``b_e`` by increments, principal axes by numpy, the accumulator
    ``v ← v + tr ε* − tr ε`` (Tampubolon et al. 2017) shifting the trial by ``v/3``."""
    p = table[0]
    be, v, work, F_old = np.eye(3), 0.0, 0.0, np.eye(3)
    out = []
    for Fd in path:
        F3 = np.eye(3)
        F3[:d, :d] = Fd
        dF = F3 @ np.linalg.inv(F_old)
        F_old = F3
        lam, V = np.linalg.eigh(dF @ be @ dF.T)
        eps_tr = 0.5 * np.log(lam)
        eps, tau = np.zeros(3), np.zeros(3)
        dp_return(eps_tr + v / 3.0, p[PCOL_K], p[PCOL_G], p[PCOL_ETA], p[PCOL_XI],
                  p[PCOL_ETA_BAR], p[PCOL_COHESION], p[PCOL_PT], 0.0, 0.0, 0.0, eps, tau)
        work += tau @ (eps_tr - eps)
        v += eps_tr.sum() - eps.sum()
        be = V @ np.diag(np.exp(2.0 * eps)) @ V.T
        sig = (V @ np.diag(tau) @ V.T)[:d, :d] / np.linalg.det(F3)
        out.append((sig, v, work))
    return out


def sheared_cycle(d, steps=60):
    """Dilate, then compact while shearing: every region of the cone, the apex and the
    correction's elastic and cone returns."""
    out = []
    for k in range(1, 3 * steps + 1):
        t = k / steps
        F = np.eye(d) * (1.0 + 0.3 * min(t, 1.0) - 0.45 * max(min(t - 1.0, 2.0), 0.0) / 2.0)
        if d > 1:
            F[0, 1] = 0.08 * max(t - 1.0, 0.0)
        out.append(F)
    return out


@pytest.mark.parametrize("material", ["rods", "cohesive"])
@pytest.mark.parametrize("d", [1, 2, 3])
@pytest.mark.parametrize("steps", [6, 60])
def test_pass_is_the_accumulator_model(material, d, steps):
    """Dilated by 30 % along each axis, then compacted to 85 % of the start while sheared: the
    pass's stress,
    plastic volume and work equal the independent model's at every step (6 steps a leg: the
    eigen path; 60: mostly the series)."""
    table = table_of(RODS if material == "rods" else COHESIVE)
    path = sheared_cycle(d, steps)
    got, want = run_pass(table, d, path), reference(table, d, path)
    K = table[0, PCOL_K]
    for (sig, state, lnJp), (sig_r, v_r, work_r) in zip(got, want):
        np.testing.assert_allclose(sig, sig_r, rtol=0, atol=1e-9 * max(np.abs(sig_r).max(), 1.0)
                                   + 1e-11 * K)
        assert lnJp == pytest.approx(v_r, abs=1e-10)
        assert state[STATE_WORK] == pytest.approx(work_r, rel=1e-8, abs=1e-12 * K)
    assert max(r[1] for r in want) > 0.1  # it did dilate
    assert want[-1][1] < max(r[1] for r in want)  # and gave volume back


def test_off_is_the_model_without_it():
    """``volume_correction = false`` writes 0 in the table's column, and the dilated volume
    stays: after the cycle ``ln J_p = ln 2``, the pressure ``K ln(0.9/2)``."""
    table = table_of(RODS, correction=False)
    assert table[0, PCOL_VOLUME_CORRECTION] == 0.0
    assert table_of(RODS)[0, PCOL_VOLUME_CORRECTION] == 1.0
    sig, _, lnJp = run_pass(table, 3, hydrostatic(3, cycle(20)))[-1]
    assert lnJp == pytest.approx(math.log(2.0), abs=1e-12)
    np.testing.assert_allclose(sig, table[0, PCOL_K] * math.log(0.45) / 0.9 * np.eye(3),
                               rtol=1e-10)
