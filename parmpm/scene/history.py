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

from parmpm.io.history_columns import (contact_names, mirror_columns, probe_columns,
                                       reaction_columns, repeated, support_columns)
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
    "plastic_strain": ("", "equivalent plastic strain (0 on elastic materials)"),
    "plastic_volume": ("", "plastic volume change ln J_p (0 on elastic materials)"),
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
    _once(c, f"{key}.fields", out["fields"])
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
        _once(c, f"{key}.stats", out["stats"])
    return out


def _once(c: Checker, key: str, names: list) -> None:
    """A probe's field or statistic listed twice would write its column twice."""
    for j, name in enumerate(names):
        if name in names[:j]:
            c.fail(f"{key}.{j}", f"{show(name)} is listed twice")


def check_columns(c: Checker, scene: dict) -> None:
    """Refuse two names that give the history the same column (a wall named ``contact1`` in a
    scene whose contact field 1 has its default name, contact names ``["a", "a_far"]`` with
    cracks): one line naming both. ``scene``: the resolved walls, boundary, contact and output.

    Each source is (its key or None, how the blamed key's value is shown, how it is named as the
    other one, its columns); the key blamed is the later of the two that the scene gave a name
    (a default or derived name has no key of its own)."""
    dim = scene["dim"]
    sources: list[tuple[str | None, str, str, list[str]]] = []
    for i, p in enumerate(scene["output"]["history"]["probes"]):
        key = f"output.history.probes.{i}.name"
        sources.append((key, show(p["name"]), f"{key} {show(p['name'])}",
                        probe_columns(p["name"], p["fields"], p["stats"])))
    for i, w in enumerate(scene.get("walls", [])):
        key = f"walls.{i}.name"
        sources.append((key, show(w["name"]), f"{key} {show(w['name'])}",
                        reaction_columns(w["name"], dim)))
    if _held(scene["boundary"]):
        sources.append((None, "", "the held boundary (its reaction)", support_columns(dim)))
    if _mirrored(scene):
        sources.append((None, "", "the mirror faces (their reaction)", mirror_columns(dim)))
    contact = scene.get("contact")
    if contact:
        n, given = len(contact["fields"]), contact.get("names", [])
        for k, name in enumerate(contact_names(given, n, contact.get("cracks", False))):
            field = k % n
            own = (f"contact.names.{field} {show(given[field])}" if given
                   else f"contact field {field} (its default name {show(f'contact{field}')})")
            if k < n:
                sources.append((f"contact.names.{k}" if given else None, show(name), own,
                                reaction_columns(name, dim)))
            else:
                sources.append((None, "", f"the crack far side {show(name)} of {own}",
                                reaction_columns(name, dim)))
    found = repeated([s[3] for s in sources])
    if found is None:
        return
    column, i, j = found
    first, second = sources[i], sources[j]
    if i == j:
        c.fail(first[0] or "output.history", f"{first[2]} gives the column {show(column)} twice")
    blamed, other = (second, first) if second[0] is not None else (first, second)
    c.fail(blamed[0] or "output.history", f"{blamed[1]} gives the column {show(column)}, which "
                                          f"{other[2]} writes too (each needs a name of its own)")


def _mirrored(scene: dict) -> bool:
    """Symmetry or clamped faces without damping or loads (as
    :func:`parmpm.output.reactions.mirrors` on the records): the mirror columns."""
    faces = [v for k, v in scene["boundary"].items() if k.endswith(("_min", "_max"))]
    return (any(side in ("symmetry", "clamped") for side in faces)
            and scene.get("damping", {}).get("coefficient", 0.0) == 0.0
            and not scene.get("loads"))


def _held(boundary: dict) -> bool:
    """Any held face or node region (as :func:`parmpm.output.reactions.held` on the record): the
    history then has the support columns."""
    faces = [v for k, v in boundary.items() if k.endswith(("_min", "_max"))]
    return (any(side in ("fixed", "slip") for side in faces) or bool(boundary["fixed_regions"])
            or bool(boundary["slip_regions"]))
