"""Scene schema, contact: ``[contact]`` makes bodies separate velocity fields that meet through
frictional contact (:mod:`parmpm.grid.contact`) instead of sharing one grid velocity.

    [contact]
    friction = 0.3                  # Coulomb's μ >= 0 between fields, or "stick" (default 0)
    fields = [[0], [1, 2]]          # optional: bodies (indices in [[bodies]]) that share a field;
                                    # default: every body its own field
    names = ["block", "table"]      # optional: one per field, naming its history columns
                                    # (default "contact<k>")
    normal = "separating"           # how a node's contact normal is found: "separating" (the
                                    # default), "heavy", "centroids", "gradient" or "average"
    gap = "column"                  # where the bodies' gap is measured at a node: "column" (the
                                    # default) or "line"
    cracks = true                   # crack faces from the damage model (default false)
    crack_damage = 1.0              # the damage at which a crack face opens (0 < D <= 1)

A scene without ``[contact]`` has one field, as before. Every body must be in exactly one field,
and there must be at least two, unless ``cracks`` is on: then every field gets a second one, the
far side of a crack (:mod:`parmpm.grid.crack`), and the default is one field of all bodies.
Crack faces need a material with a damage model. Every problem is one line naming the key, the
value and what was expected.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from parmpm.io.history_columns import contact_names
from parmpm.scene.check import Checker, show

CONTACT_KEYS = ("friction", "fields", "normal", "gap", "cracks", "crack_damage", "names")
#: ``normal``: how a node's contact normal is found (:mod:`parmpm.grid.contact`)
NORMALS = ("separating", "heavy", "centroids", "gradient", "average")
#: ``gap``: where the gap between the fields is measured at a node
GAPS = ("column", "line")
#: the most velocity fields a scene may have (each costs a grid's memory and a transfer pass;
#: with cracks every field has a far side: half as many body fields)
MAX_FIELDS = 16


@dataclass(frozen=True, slots=True)
class Contact:
    """``fields``: per field, its bodies' indices; ``friction``: μ or "stick"; ``normal``,
    ``gap``: how the contact finds a node's normal and gap; ``cracks``: crack faces from the
    damage model, opening at ``crack_damage``."""

    fields: tuple[tuple[int, ...], ...]
    friction: float | str
    normal: str = "separating"
    gap: str = "column"
    cracks: bool = False
    crack_damage: float = 1.0
    names: tuple[str, ...] = ()

    def column_names(self) -> tuple[str, ...]:
        """Every velocity field's history name: its given name or ``contact<k>``, and with
        cracks each one's far side, ``<name>_far``."""
        return contact_names(self.names, len(self.fields), self.cracks)

    @property
    def velocity_fields(self) -> int:
        """How many velocity fields: the body fields, and with cracks each one's far side."""
        return len(self.fields) * (2 if self.cracks else 1)

    @property
    def mu(self) -> float:
        return math.inf if self.friction == "stick" else float(self.friction)

    def field_of_body(self, n_bodies: int) -> tuple[int, ...]:
        """The field of every body, in body order."""
        out = [0] * n_bodies
        for k, members in enumerate(self.fields):
            for b in members:
                out[b] = k
        return tuple(out)


def check_contact(c: Checker, raw: Any, n_bodies: int, materials: dict, taken: set) -> dict:
    """The resolved ``[contact]`` (``materials``: the resolved table, for what cracks need;
    ``taken``: the walls' and loads' names, which share the history's columns)."""
    t = c.table("contact", raw, CONTACT_KEYS)
    cracks = t.get("cracks", False)
    if not isinstance(cracks, bool):
        c.expected("contact.cracks", "true or false", cracks)
    crack_damage = None
    if "crack_damage" in t:
        if not cracks:
            c.fail("contact.crack_damage", "used only with contact.cracks = true")
        crack_damage = c.number("contact.crack_damage", t["crack_damage"],
                                "a damage 0 < D <= 1", lambda x: 0.0 < x <= 1.0)
    if cracks:
        _crack_needs(c, materials, 1.0 if crack_damage is None else crack_damage)
    friction = t.get("friction", 0.0)
    if friction != "stick":
        friction = c.number("contact.friction", friction, 'a number >= 0 or "stick"',
                            lambda x: x >= 0)
    normal = c.string("contact.normal", t.get("normal", "separating"))
    if normal not in NORMALS:
        c.expected("contact.normal", " | ".join(f'"{n}"' for n in NORMALS), normal)
    gap = c.string("contact.gap", t.get("gap", "column"))
    if gap not in GAPS:
        c.expected("contact.gap", " | ".join(f'"{g}"' for g in GAPS), gap)
    limit = MAX_FIELDS // 2 if cracks else MAX_FIELDS
    if "fields" not in t:
        fields = [list(range(n_bodies))] if cracks else [[b] for b in range(n_bodies)]
        if len(fields) > limit:  # the default is held to the limit a list is
            c.fail("contact.fields", f"not given, so each of the {n_bodies} bodies would be a "
                                     f"field of its own: more than the {limit} a scene may have "
                                     "(each costs a grid's memory); give contact.fields, with "
                                     "bodies that never meet sharing a field")
    else:
        fields = _fields(c, t["fields"], n_bodies, limit)
    if len(fields) < 2 and not cracks:
        c.fail("contact.fields" if "fields" in t else "contact",
               f"expected at least two fields (the scene has {n_bodies} "
               f"{'body' if n_bodies == 1 else 'bodies'}): one field is the run without [contact]")
    out = {"friction": friction, "fields": fields, "normal": normal}
    if gap != "column":  # absent otherwise: scenes without it resolve as they did
        out["gap"] = gap
    if "names" in t:  # absent otherwise: scenes without names resolve as they did
        out["names"] = _names(c, t["names"], len(fields), taken)
    if cracks:  # absent otherwise: scenes without cracks resolve as they did
        out["cracks"] = True
        out["crack_damage"] = 1.0 if crack_damage is None else crack_damage
    return out


def _names(c: Checker, raw: Any, n_fields: int, taken: set) -> list:
    """One history name per field: 1 to 40 letters, digits, '_' or '-', none used twice (nor by a
    wall or load)."""
    if not isinstance(raw, list) or len(raw) != n_fields:
        c.expected("contact.names", f"a list of {n_fields} names, one per field", raw)
    out = []
    for k, name in enumerate(raw):
        key = f"contact.names.{k}"
        name = c.string(key, name)
        if not name or not all(ch.isalnum() or ch in "_-" for ch in name) or len(name) > 40:
            c.expected(key, "1 to 40 letters, digits, '_' or '-' (it names history columns)",
                       name)
        if name in taken or name in out:
            c.fail(key, f"{show(name)} is used twice (each field, wall and load needs its own)")
        out.append(name)
    return out


def _crack_needs(c: Checker, materials: dict, crack_damage: float) -> None:
    """What crack faces need of the scene's materials (module doc)."""
    damaged = {n: m["damage"] for n, m in materials.items() if m.get("damage")}
    if not damaged:
        c.fail("contact.cracks", "no material has a damage model ([materials.NAME.damage]): "
                                 "nothing can crack")
    if crack_damage >= 1.0 and all(d["softening"] == "exponential" for d in damaged.values()):
        c.fail("contact.crack_damage", f"exponential softening never reaches D = 1 (materials "
                                       f"{show(sorted(damaged))}): give a crack_damage below 1")


def _fields(c: Checker, raw: Any, n_bodies: int, limit: int) -> list:
    what = (f"a list of at most {limit} lists of body indices (0 to {n_bodies - 1}), "
            "every body in exactly one")
    if not isinstance(raw, list) or not raw or len(raw) > limit:
        c.expected("contact.fields", what, raw)
    seen: dict[int, int] = {}
    out = []
    for k, members in enumerate(raw):
        key = f"contact.fields.{k}"
        if not isinstance(members, list) or not members:
            c.expected(key, "a nonempty list of body indices", members)
        field = []
        for j, b in enumerate(members):
            b = c.integer(f"{key}.{j}", b, f"a body index (0 to {n_bodies - 1})",
                          lambda v: 0 <= v < n_bodies)
            if b in seen:
                c.fail(f"{key}.{j}", f"body {b} is already in field {seen[b]} (every body in "
                                     "exactly one field)")
            seen[b] = k
            field.append(b)
        out.append(field)
    missing = [b for b in range(n_bodies) if b not in seen]
    if missing:
        c.fail("contact.fields", f"bodies {show(missing)} are in no field (every body in "
                                 "exactly one)")
    return out
