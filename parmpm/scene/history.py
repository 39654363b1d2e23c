"""Scene schema of ``[output.history]``: the history's schedule and its probes.

    [output.history]            # or output.history = false (no history, no per-step ledger)
    every_steps = 10            # or every = 1e-3 (s); default: about 200 rows per run
    [[output.history.probes]]
    name = "tip"                # names the columns: tip.u.y, tip.stress.yy
    point = [0.5, -0.9]         # the particle that started nearest this point
    fields = ["u.y", "stress.yy"]
    [[output.history.probes]]
    name = "top"
    region = {min = [0.0, -0.3], max = [0.2, 0.0]}   # particles that started in this box,
    field = "stress.yy"         # or body = 0 (index in [[bodies]]), or material = "rubber"
    stats = ["mean", "max"]     # of mean (mass-weighted), min, max; default all three
"""
from __future__ import annotations

import re
from typing import Any

from parmpm.scene.check import Checker, show

AXES = "xyz"
#: probe fields: name → (components, description); components "" (scalar), "v" (vector), "t"
#: (tensor)
PROBE_FIELDS = {
    "x": ("v", "position (m)"),
    "u": ("v", "displacement x − X (m)"),
    "v": ("v", "velocity (m/s)"),
    "stress": ("t", "Cauchy stress (Pa)"),
    "F": ("t", "deformation gradient"),
    "J": ("", "volume ratio det F"),
    "stretch": ("", "largest principal stretch √(max eig F Fᵀ)"),
    "damage": ("", "damage D"),
}
PROBE_STATS = ("mean", "min", "max")


def field_names(dim: int) -> list[str]:
    """Every probe field name valid in ``dim`` dimensions (``u.y``, ``stress.xy``, ``J``, ...)."""
    out = []
    for name, (kind, _) in PROBE_FIELDS.items():
        if kind == "":
            out.append(name)
        elif kind == "v":
            out += [f"{name}.{AXES[a]}" for a in range(dim)]
        else:
            out += [f"{name}.{AXES[a]}{AXES[b]}" for a in range(dim) for b in range(dim)]
    return out



HISTORY_KEYS = ("enabled", "every", "every_steps", "probes")
PROBE_KEYS = ("name", "point", "region", "body", "material", "field", "fields", "stats")
#: rows per run when the scene gives no schedule
DEFAULT_ROWS = 200
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")


def history(c: Checker, raw: Any, time: dict, dim: int, bodies: list, materials: dict) -> dict:
    """The resolved ``output.history`` table (``enabled`` false: none)."""
    if isinstance(raw, bool):
        raw = {"enabled": raw}
    t = c.table("output.history", raw, HISTORY_KEYS)
    enabled = c.boolean("output.history.enabled", t.get("enabled", True))
    every, every_steps = c.schedule("output.history", t, time, DEFAULT_ROWS)
    raw_probes = t.get("probes", [])
    if not isinstance(raw_probes, list) or not all(isinstance(p, dict) for p in raw_probes):
        c.expected("output.history.probes", "an array of tables ([[output.history.probes]])",
                   raw_probes)
    probes = [_probe(c, f"output.history.probes.{i}", p, dim, bodies, materials)
              for i, p in enumerate(raw_probes)]
    names = [p["name"] for p in probes]
    for i, name in enumerate(names):
        if name in names[:i]:
            c.fail(f"output.history.probes.{i}.name", f"{show(name)} names two probes")
    return {"enabled": enabled, "every": every, "every_steps": every_steps, "probes": probes}


def _probe(c: Checker, key: str, raw: dict, dim: int, bodies: list, materials: dict) -> dict:
    t = c.table(key, raw, PROBE_KEYS)
    if "name" not in t:
        c.fail(f"{key}.name", "missing (a name for the probe's columns)")
    name = c.string(f"{key}.name", t["name"])
    if not _NAME.fullmatch(name):
        c.expected(f"{key}.name", "a name of letters, digits, _ and - starting with a letter",
                   name)
    where = [k for k in ("point", "region", "body", "material") if k in t]
    if len(where) != 1:
        c.fail(key, "expected exactly one of point, region, body, material, got "
               + (", ".join(where) if where else "none"))
    out = {"name": name, "point": None, "region": None, "body": None, "material": None}
    kind = where[0]
    if kind == "point":
        out["point"] = c.vector(f"{key}.point", t["point"], dim, "float", broadcast=False)
    elif kind == "region":
        r = c.table(f"{key}.region", t["region"], ("min", "max"))
        if "min" not in r or "max" not in r:
            c.fail(f"{key}.region", "expected a table {min = [...], max = [...]}")
        lo = c.vector(f"{key}.region.min", r["min"], dim, "float", broadcast=False)
        hi = c.vector(f"{key}.region.max", r["max"], dim, "float", broadcast=False)
        if any(a > b for a, b in zip(lo, hi)):
            c.fail(f"{key}.region", f"min {lo} exceeds max {hi} on some axis")
        out["region"] = {"min": lo, "max": hi}
    elif kind == "body":
        out["body"] = c.integer(f"{key}.body", t["body"],
                                f"an index of [[bodies]] (0 to {len(bodies) - 1})",
                                lambda b: 0 <= b < len(bodies))
    else:
        out["material"] = c.choice(f"{key}.material", t["material"], tuple(materials))
    if ("field" in t) == ("fields" in t):
        c.fail(key, "expected one of field (a name) or fields (a list of names)")
    fields = [t["field"]] if "field" in t else t["fields"]
    valid = tuple(field_names(dim))
    if not isinstance(fields, list) or not fields:
        c.expected(f"{key}.fields", "a non-empty list of field names", fields)
    out["fields"] = [c.choice(f"{key}.fields", f, valid) for f in fields]
    if kind == "point":
        if t.get("stats", []) != []:  # [] is what a resolved scene holds
            c.fail(f"{key}.stats", "a point probe reads one particle: stats apply to region, "
                                   "body and material probes")
        out["stats"] = []
    else:
        stats = t.get("stats", list(PROBE_STATS))
        if not isinstance(stats, list) or not stats:
            c.expected(f"{key}.stats", 'a non-empty list of "mean", "min", "max"', stats)
        out["stats"] = [c.choice(f"{key}.stats", s, PROBE_STATS) for s in stats]
    return out
