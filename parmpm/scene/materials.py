"""Scene schema, materials: ``[materials.NAME]`` tables — model, density, elastic moduli — and
their optional ``[materials.NAME.damage]``.

Split from :mod:`parmpm.scene.schema` (which calls :func:`check_materials`); the same conventions:
every problem is a one-line ``SceneError`` naming the key, the value and what was expected.
"""
from __future__ import annotations

import math
from typing import Any

from parmpm.materials import MODELS, SOFTENING, lame
from parmpm.scene.check import Checker

MATERIAL_KEYS = ("model", "density", "youngs_modulus", "poisson_ratio", "damage")
DAMAGE_KEYS = ("criterion", "onset", "fracture", "softening", "freeze")


def check_materials(c: Checker, raw: Any) -> dict:
    """The resolved ``[materials]`` table: name → model, density, moduli, optional damage."""
    if not isinstance(raw, dict) or not raw:
        c.expected("materials", "at least one [materials.NAME] table", raw)
    out = {}
    for name, spec in raw.items():
        key = f"materials.{name}"
        t = c.table(key, spec, MATERIAL_KEYS)
        model = c.choice(f"{key}.model", c.required(key, t, "model", " or ".join(f'"{m}"' for m in MODELS)),
                         tuple(MODELS))
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
        if t.get("damage") is not None:
            out[name]["damage"] = _damage(c, f"{key}.damage", t["damage"])
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
