"""Scene schema, contact: ``[contact]`` makes bodies separate velocity fields that meet through
frictional contact (:mod:`parmpm.grid.contact`) instead of sharing one grid velocity.

    [contact]
    friction = 0.3                  # Coulomb's μ >= 0 between fields, or "stick" (default 0)
    fields = [[0], [1, 2]]          # optional: bodies (indices in [[bodies]]) that share a field;
                                    # default: every body its own field
    normal = "centroids"            # how a node's contact normal is found (the one method)

A scene without ``[contact]`` has one field, as before. Every body must be in exactly one field,
and there must be at least two: one field is the single-field run. Every problem is one line
naming the key, the value and what was expected.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from parmpm.scene.check import Checker, show

CONTACT_KEYS = ("friction", "fields", "normal")
NORMALS = ("centroids",)
#: the most velocity fields a scene may have (each costs a grid's memory and a transfer pass)
MAX_FIELDS = 16


@dataclass(frozen=True, slots=True)
class Contact:
    """``fields``: per field, its bodies' indices; ``friction``: μ or "stick"; ``normal``."""

    fields: tuple[tuple[int, ...], ...]
    friction: float | str
    normal: str = "centroids"

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


def check_contact(c: Checker, raw: Any, n_bodies: int) -> dict:
    """The resolved ``[contact]``."""
    t = c.table("contact", raw, CONTACT_KEYS)
    friction = t.get("friction", 0.0)
    if friction != "stick":
        friction = c.number("contact.friction", friction, 'a number >= 0 or "stick"',
                            lambda x: x >= 0)
    normal = c.string("contact.normal", t.get("normal", "centroids"))
    if normal not in NORMALS:
        c.expected("contact.normal", " | ".join(f'"{n}"' for n in NORMALS), normal)
    if "fields" not in t:
        fields = [[b] for b in range(n_bodies)]
    else:
        fields = _fields(c, t["fields"], n_bodies)
    if len(fields) < 2:
        c.fail("contact.fields" if "fields" in t else "contact",
               f"expected at least two fields (the scene has {n_bodies} "
               f"{'body' if n_bodies == 1 else 'bodies'}): one field is the run without [contact]")
    return {"friction": friction, "fields": fields, "normal": normal}


def _fields(c: Checker, raw: Any, n_bodies: int) -> list:
    what = (f"a list of at most {MAX_FIELDS} lists of body indices (0 to {n_bodies - 1}), "
            "every body in exactly one")
    if not isinstance(raw, list) or not raw or len(raw) > MAX_FIELDS:
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
