"""When a damageable bar pulled at its ends fails: the stretch the damage parameters predict.

A bar of segments in series (each one material, spanning the whole cross-section) is pulled
slowly, so every cross-section carries the same nominal stress ``P`` (force per reference area).
Each segment's law in uniaxial tension is ``P_i(λ) = (1 − g_i(λ))·P_e,i(λ)``, with ``g`` the
softening of :mod:`parmpm.materials.damage` (driven by the largest principal stretch, here the
axial one ``λ``) and ``P_e`` the elastic law:

* 1D, uniaxial strain: ``P_e = [μ(λ² − 1) + λ_L ln λ]/λ`` (neo-Hookean), ``(λ_L + 2μ)(λ − 1)``;
* 2D (plane strain) and 3D, laterally free: the lateral stretch ``λ_t`` makes the lateral stress
  zero, ``μ(λ_t² − 1) + λ_L ln(λ λ_t^k) = 0`` with ``k = d − 1``, and then
  ``P_e = σ_xx·λ_t^k = μ(λ² − λ_t²)/λ`` (neo-Hookean); small-strain linear elasticity gives
  ``E/(1 − ν²)·(λ − 1)`` in 2D and ``E(λ − 1)`` in 3D. Degradation keeps the lateral stress zero
  (it scales the whole tensor in tension), so ``λ_t`` is the undamaged one.

The segment with the lowest peak ``P_pk = max P_i`` fails: past its peak it softens, and since the
rest of the bar unloads elastically when the force drops (a snap-back for any segment shorter than
the bar), it fails at once, at the bar's stretch when it peaked:

    λ_fail = Σ_i L_i λ_i / Σ_i L_i,   P_i(λ_i) = P_pk on the rising branch of every other segment.

That is the prediction :class:`parmpm.output.metrics.tension.TensionBarMetrics` compares with the run.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.exact.bars import lame_parameters, nominal_stress_1d


def _lateral_stretch(stretch, lam: float, mu: float, k: int):
    """``λ_t`` with ``μ(λ_t² − 1) + λ_L ln(λ λ_t^k) = 0`` (increasing in ``λ_t``), by bisection
    to round-off (64 halvings of ``[1e-6, 2]``); plain floats for a scalar (the peak search
    calls this hundreds of times), numpy for arrays."""
    if np.ndim(stretch) == 0:
        s, lo, hi = float(stretch), 1e-6, 2.0
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            if mu * (mid * mid - 1.0) + lam * math.log(s * mid ** k) < 0:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)
    lo = np.full_like(stretch, 1e-6)
    hi = np.full_like(stretch, 2.0)
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        f = mu * (mid * mid - 1.0) + lam * np.log(stretch * mid ** k)
        lo, hi = np.where(f < 0, mid, lo), np.where(f < 0, hi, mid)
    return 0.5 * (lo + hi)


def elastic_tension(model: str, E: float, nu: float, dim: int):
    """``P_e(λ)``, the nominal axial stress of a bar in uniaxial tension (see the module doc)."""
    if dim == 1:
        return nominal_stress_1d(model, E, nu)
    lam, mu = lame_parameters(E, nu)
    k = dim - 1
    if model == "neo_hookean":
        def stress(stretch):
            if np.ndim(stretch) == 0:
                s = float(stretch)
            else:
                s = np.asarray(stretch, dtype=float)
            t = _lateral_stretch(s, lam, mu, k)
            return mu * (s * s - t * t) / s
    elif model == "linear_elastic":
        modulus = E / (1.0 - nu * nu) if dim == 2 else E

        def stress(stretch):
            return modulus * (np.asarray(stretch, dtype=float) - 1.0)
    else:
        raise SceneError(f"no uniaxial tension law for material model {model!r}")
    return stress


def softening(stretch, damage: dict | None):
    """``g(λ)`` of a material's damage table (None: no damage), as the kernels compute it."""
    s = np.asarray(stretch, dtype=float)
    if damage is None:
        return np.zeros_like(s)
    x = np.maximum(s - damage["onset"], 0.0) / (damage["fracture"] - damage["onset"])
    if damage["softening"] == "exponential":
        return 1.0 - np.exp(-x)
    return np.minimum(x, 1.0)


def _peak(law, damage, samples: int = 20001) -> tuple[float, float]:
    """(``λ_pk``, ``P_pk``): the largest degraded stress and where it is reached."""
    top = damage["onset"] + 6.0 * (damage["fracture"] - damage["onset"]) \
        if damage["softening"] == "exponential" else damage["fracture"]
    lam = np.linspace(1.0, top, samples)
    P = (1.0 - softening(lam, damage)) * law(lam)
    i = int(np.argmax(P))
    a, b = lam[max(i - 1, 0)], lam[min(i + 1, samples - 1)]
    for _ in range(80):  # golden-section refinement of the sampled maximum (to round-off)
        c, d = b - 0.618033988749895 * (b - a), a + 0.618033988749895 * (b - a)
        fc = (1.0 - softening(c, damage)) * law(c)
        fd = (1.0 - softening(d, damage)) * law(d)
        a, b = (a, d) if fc >= fd else (c, b)
    s = 0.5 * (a + b)
    return float(s), float((1.0 - softening(s, damage)) * law(s))


def _rising(law, damage, target: float, top: float) -> float:
    """``λ`` in ``[1, top]`` with ``(1 − g)·P_e = target`` on the rising branch (bisection)."""
    lo, hi = 1.0, top
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        if (1.0 - softening(mid, damage)) * law(mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def tension_failure(segments: list[dict], dim: int) -> dict:
    """Failure of a bar of ``segments`` (dicts: ``length``, ``model``, ``E``, ``nu``, ``damage``)
    in series: ``{"stretch", "peak_stress", "weakest", "segment_stretches"}`` (module doc).
    ``None`` when no segment can soften (the bar never fails)."""
    laws = [elastic_tension(s["model"], s["E"], s["nu"], dim) for s in segments]
    peaks = [(_peak(law, s["damage"]) if s["damage"] is not None else None)
             for law, s in zip(laws, segments)]
    candidates = [(p[1], i) for i, p in enumerate(peaks) if p is not None]
    if not candidates:
        return None
    P_pk, weakest = min(candidates)
    stretches = []
    for i, (law, seg) in enumerate(zip(laws, segments)):
        if i == weakest:
            stretches.append(peaks[i][0])
            continue
        top = peaks[i][0] if peaks[i] is not None else 2.0
        while peaks[i] is None and law(top) < P_pk:  # undamaged: widen the bracket
            top = 1.0 + 2.0 * (top - 1.0)
        stretches.append(_rising(law, seg["damage"], P_pk, top))
    lengths = np.array([s["length"] for s in segments])
    stretch = float(np.dot(lengths, stretches) / lengths.sum())
    return {"stretch": stretch, "peak_stress": P_pk, "weakest": weakest,
            "segment_stretches": [float(s) for s in stretches]}


def opening_allowance(segments: list[dict], weakest: int, cell: float) -> float:
    """Largest bar-stretch increment from failure to numerical separation: the failed segment
    stretching on to ``λ_f`` and a gap of two cells (the most two particle supports can need to
    stop sharing a node), all supplied by the grips, none by the rest's elastic recoil."""
    seg = segments[weakest]
    length = sum(s["length"] for s in segments)
    return ((seg["damage"]["fracture"] - 1.0) * seg["length"] + 2.0 * cell) / length


__all__ = ["elastic_tension", "softening", "tension_failure", "opening_allowance"]
