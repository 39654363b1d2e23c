"""Scene schema, materials: ``[materials.NAME]`` tables — model, density, elastic moduli — their
optional ``[materials.NAME.damage]``, and the flat keys of the plastic models (``"j2"``,
``"drucker_prager"``: :mod:`parmpm.materials.plasticity`).

Split from :mod:`parmpm.scene.schema` (which calls :func:`check_materials`); the same conventions:
every problem is a one-line ``SceneError`` naming the key, the value and what was expected.
"""
from __future__ import annotations

import math
from typing import Any

from parmpm.core.errors import SceneError
from parmpm.materials import MODELS, PLASTIC_MODELS, SOFTENING, lame
from parmpm.scene.check import Checker

ELASTIC_KEYS = ("model", "density", "youngs_modulus", "poisson_ratio")
#: a j2 material's keys beyond the elastic ones; which hardening law takes which: HARDENING_KEYS
J2_KEYS = ("yield_stress", "hardening", "hardening_modulus", "hardening_exponent",
           "strength_coefficient", "rate_coefficient", "reference_rate")
HARDENING_KEYS = {"linear": ("hardening_modulus",),
                  "swift": ("strength_coefficient", "hardening_exponent"),
                  "johnson_cook": ("hardening_modulus", "hardening_exponent", "rate_coefficient",
                                   "reference_rate")}
#: μ(I)'s keys on a drucker_prager material: friction_angle_2 turns it on
INERTIAL_KEYS = ("friction_angle_2", "inertial_number_0", "grain_diameter", "grain_density")
DRUCKER_PRAGER_KEYS = ("friction_angle", "dilatancy_angle", "cohesion", "matching",
                       "tension_cutoff", "volume_correction", *INERTIAL_KEYS)
#: the keys each model takes (a plastic model takes no damage model yet)
MODEL_KEYS = {**{m: (*ELASTIC_KEYS, "damage") for m in MODELS},
              "j2": (*ELASTIC_KEYS, *J2_KEYS),
              "drucker_prager": (*ELASTIC_KEYS, *DRUCKER_PRAGER_KEYS)}
MATERIAL_KEYS = (*ELASTIC_KEYS, "damage", *J2_KEYS, *DRUCKER_PRAGER_KEYS)
DAMAGE_KEYS = ("criterion", "onset", "fracture", "softening", "freeze")
#: every model's name, the elastic laws first
MODEL_NAMES = (*MODELS, *PLASTIC_MODELS)


def check_materials(c: Checker, raw: Any) -> dict:
    """The resolved ``[materials]`` table: name → model, density, moduli, optional damage, and a
    plastic model's keys with their defaults filled in."""
    if not isinstance(raw, dict) or not raw:
        c.expected("materials", "at least one [materials.NAME] table", raw)
    out = {}
    for name, spec in raw.items():
        key = f"materials.{name}"
        t = c.table(key, spec, MATERIAL_KEYS)
        model = c.choice(f"{key}.model",
                         c.required(key, t, "model", " or ".join(f'"{m}"' for m in MODEL_NAMES)),
                         MODEL_NAMES)
        _keys_of_model(c, key, t, model)
        out[name] = {
            "model": model,
            "density": c.number(f"{key}.density", c.required(key, t, "density", "a number > 0"),
                                "a number > 0 (kg/m^dim)", lambda x: x > 0),
            "youngs_modulus": c.number(
                f"{key}.youngs_modulus", c.required(key, t, "youngs_modulus", "a number > 0"),
                "a number > 0 (Pa)", lambda x: x > 0),
            "poisson_ratio": c.number(
                f"{key}.poisson_ratio", c.required(key, t, "poisson_ratio", "-1 < nu < 0.5"),
                "a number with -1 < nu < 0.5", lambda x: -1 < x < 0.5),
        }
        m = out[name]
        lam, mu = lame(m["youngs_modulus"], m["poisson_ratio"])
        c2 = (lam + 2 * mu) / m["density"]
        if not (math.isfinite(c2) and c2 > 0 and math.isfinite(1 / m["density"])
                and mu > 0 and math.isfinite(lam)):
            c.fail(key, f"youngs_modulus {m['youngs_modulus']:g} Pa, poisson_ratio "
                        f"{m['poisson_ratio']:g} and density {m['density']:g} give a wave speed "
                        f"squared of {c2:g} m^2/s^2 (Lame constants {lam:g}, {mu:g}); expected a "
                        "positive, finite wave speed (moduli and density of normal magnitude)")
        if model == "j2":
            m.update(_j2(c, key, t))
        elif model == "drucker_prager":
            m.update(_drucker_prager(c, key, t))
        elif t.get("damage") is not None:
            m["damage"] = _damage(c, f"{key}.damage", t["damage"])
    return out


def _keys_of_model(c: Checker, key: str, t: dict, model: str) -> None:
    """Refuse a key of another model (a yield stress on a neo-Hookean material would be
    silently ignored), and damage on a plastic model (none of its kernels degrade yet)."""
    if model in PLASTIC_MODELS and "damage" in t:
        c.fail(f"{key}.damage", f"not available with model '{model}' (plastic materials take no "
                                "damage model yet)")
    for name in t:
        if name not in MODEL_KEYS[model]:
            c.fail(f"{key}.{name}", f"not a key of model '{model}' (it takes "
                                    f"{', '.join(MODEL_KEYS[model])})")


def _j2(c: Checker, key: str, t: dict) -> dict:
    """A j2 material's yield stress and hardening law (:mod:`parmpm.materials.plasticity.hardening`),
    every key of the law with its default."""
    # imported here: the plasticity modules load numba, which reading an elastic scene must not
    from parmpm.materials.plasticity.hardening import HARDENING, swift_eps0

    sigma_y = c.number(f"{key}.yield_stress",
                       c.required(key, t, "yield_stress", "a number > 0 (Pa)"),
                       "a number > 0 (Pa)", lambda x: x > 0)
    law = c.choice(f"{key}.hardening", t.get("hardening", "linear"), tuple(HARDENING))
    for name in J2_KEYS:
        if name in t and name not in ("yield_stress", "hardening", *HARDENING_KEYS[law]):
            c.fail(f"{key}.{name}", f'not used by hardening "{law}" (it takes '
                                    f"{', '.join(HARDENING_KEYS[law])})")
    out: dict[str, Any] = {"yield_stress": sigma_y, "hardening": law}

    def exponent() -> float:
        return c.number(f"{key}.hardening_exponent",
                        c.required(key, t, "hardening_exponent", "a number 0 < n <= 1"),
                        "a number 0 < n <= 1", lambda x: 0 < x <= 1)

    def modulus() -> float:
        return c.number(f"{key}.hardening_modulus", t.get("hardening_modulus", 0.0),
                        "a number >= 0 (Pa)", lambda x: x >= 0)

    if law == "linear":
        out["hardening_modulus"] = modulus()
    elif law == "swift":
        a = c.number(f"{key}.strength_coefficient",
                     c.required(key, t, "strength_coefficient", "a number > 0 (Pa)"),
                     "a number > 0 (Pa)", lambda x: x > 0)
        n = exponent()
        try:
            eps0 = swift_eps0(sigma_y, a, n)
        except OverflowError:
            eps0 = math.inf
        if not (math.isfinite(eps0) and eps0 > 0):
            c.fail(key, f"yield_stress {sigma_y:g} Pa, strength_coefficient {a:g} Pa and "
                        f"hardening_exponent {n:g} give the Swift strain offset eps0 = "
                        f"(yield_stress/strength_coefficient)^(1/n) = {eps0:g}; expected a "
                        "finite eps0 > 0")
        out.update(strength_coefficient=a, hardening_exponent=n)
    else:
        out.update(hardening_modulus=modulus(), hardening_exponent=exponent(),
                   rate_coefficient=c.number(f"{key}.rate_coefficient",
                                             t.get("rate_coefficient", 0.0),
                                             "a number >= 0 (0: no rate term)", lambda x: x >= 0),
                   reference_rate=c.number(f"{key}.reference_rate", t.get("reference_rate", 1.0),
                                           "a number > 0 (1/s)", lambda x: x > 0))
    return out


def _drucker_prager(c: Checker, key: str, t: dict) -> dict:
    """A drucker_prager material's angles, cohesion, matching, cut-off and volume correction
    (a boolean, default false), checked by
    :func:`parmpm.materials.plasticity.drucker_prager.drucker_prager_constants` (the ranges are
    its own); absent ``tension_cutoff`` stays None (the apex, infinite for φ = 0)."""
    from parmpm.materials.plasticity.drucker_prager import drucker_prager_constants  # numba: _j2

    out = {
        "friction_angle": c.number(
            f"{key}.friction_angle",
            c.required(key, t, "friction_angle", "an angle 0 <= phi < 90 (degrees)"),
            "an angle 0 <= phi < 90 (degrees)"),
        "dilatancy_angle": c.number(f"{key}.dilatancy_angle", t.get("dilatancy_angle", 0.0),
                                    "an angle 0 <= psi <= friction_angle (degrees)"),
        "cohesion": c.number(f"{key}.cohesion", t.get("cohesion", 0.0), "a number >= 0 (Pa)"),
        "matching": t.get("matching", "plane_strain"),
        "tension_cutoff": None if t.get("tension_cutoff") is None else c.number(
            f"{key}.tension_cutoff", t["tension_cutoff"], "a mean stress 0 <= p_t <= the apex (Pa)"),
        "volume_correction": c.boolean(f"{key}.volume_correction",
                                       t.get("volume_correction", False)),
    }
    try:
        drucker_prager_constants(out["friction_angle"], out["dilatancy_angle"], out["cohesion"],
                                 out["matching"], out["tension_cutoff"], where=key)
    except SceneError as err:  # its message names the material; add the scene and the --set
        c.fail(key, str(err).removeprefix(f"{key}: "))
    if any(t.get(k) is not None for k in INERTIAL_KEYS):
        out.update(_inertial(c, key, t, out["friction_angle"], out["cohesion"]))
    return out


def _inertial(c: Checker, key: str, t: dict, phi: float, cohesion: float) -> dict:
    """μ(I)'s keys (:mod:`parmpm.materials.plasticity.inertial`): ``friction_angle_2`` (φ < φ_2
    < 90), ``inertial_number_0`` and ``grain_diameter`` (> 0) required together,
    ``grain_density`` (> 0) optional; the rheology is for cohesionless grains."""
    angle = f"an angle friction_angle ({phi:g}) < phi_2 < 90 (degrees)"
    out = {
        "friction_angle_2": c.number(
            f"{key}.friction_angle_2", c.required(key, t, "friction_angle_2", angle), angle,
            lambda x: phi < x < 90.0),
        "inertial_number_0": c.number(
            f"{key}.inertial_number_0",
            c.required(key, t, "inertial_number_0", "a number > 0 (mu(I)'s I_0)"),
            "a number > 0 (mu(I)'s I_0)", lambda x: x > 0),
        "grain_diameter": c.number(
            f"{key}.grain_diameter",
            c.required(key, t, "grain_diameter", "a length > 0 (m)"), "a length > 0 (m)",
            lambda x: x > 0),
        "grain_density": None if t.get("grain_density") is None else c.number(
            f"{key}.grain_density", t["grain_density"], "a number > 0 (the units of density)", lambda x: x > 0),
    }
    if cohesion != 0.0:
        c.fail(f"{key}.cohesion", f"mu(I) (friction_angle_2) is for cohesionless grains: "
               f"expected 0, got {cohesion:g}")
    return out


def _freeze(c: Checker, key: str, value: Any) -> float | str:
    """The damage at which a CPDI domain freezes: 0 < D <= 1, or "never" (kept as the word, so
    the resolved scene reads back; the material table stores it as 2, a damage never reached)."""
    if value == "never":
        return "never"
    return c.number(key, value, 'a damage 0 < D <= 1 or "never"', lambda x: 0.0 < x <= 1.0)


def _damage(c: Checker, key: str, raw: Any) -> dict:
    """``[materials.NAME.damage]``: the stretch-driven damage of :mod:`parmpm.materials.damage`."""
    t = c.table(key, raw, DAMAGE_KEYS)
    onset = c.number(f"{key}.onset", c.required(key, t, "onset", "a stretch >= 1"),
                     "a stretch >= 1 (largest principal stretch where damage starts)",
                     lambda x: x >= 1.0)
    return {
        "criterion": c.choice(f"{key}.criterion", t.get("criterion", "max_principal_stretch"),
                              ("max_principal_stretch",)),
        "onset": onset,
        "fracture": c.number(f"{key}.fracture", c.required(key, t, "fracture", f"a stretch > {onset}"),
                             f"a stretch > onset ({onset:g})", lambda x: x > onset),
        "softening": c.choice(f"{key}.softening", t.get("softening", "linear"), tuple(SOFTENING)),
        "freeze": _freeze(c, f"{key}.freeze", t.get("freeze", 1.0)),
    }
