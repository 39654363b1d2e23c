"""Scene schema, CSG shapes: a body's ``parts`` (union, difference, intersection of primitives
and of each other, nested) and the primitives only CSG brings (cylinder, polygon, half-space).

Called by :mod:`parmpm.scene.bodies` for a body whose shape is not a box, disk or sphere. Every
problem is one line naming the full key (``bodies.0.parts.1.radius``), the value and what was
expected; the geometry itself is :mod:`parmpm.geometry.csg`.
"""
from __future__ import annotations

import math
from typing import Any

from parmpm.geometry import csg
from parmpm.scene.check import AXIS_NAMES, Checker, show
from parmpm.scene.records import Part, build

#: dimensions each shape exists in (a part's or a body's)
PART_DIMS = {"box": (1, 2, 3), "disk": (2,), "sphere": (3,), "cylinder": (3,), "polygon": (2,),
             "half_space": (1, 2, 3), "union": (1, 2, 3), "difference": (1, 2, 3),
             "intersection": (1, 2, 3)}
#: each shape's own keys (``shape`` aside)
PART_KEYS = {"box": ("min", "max", "angle"), "disk": ("center", "radius"),
             "sphere": ("center", "radius"), "cylinder": ("axis", "center", "radius", "length"),
             "polygon": ("vertices",), "half_space": ("point", "normal"),
             "union": ("parts",), "difference": ("parts",), "intersection": ("parts",)}
ALL_PART_KEYS = ("shape", "min", "max", "angle", "center", "radius", "axis", "length", "vertices",
                 "point", "normal", "parts")
#: how deep combinations nest (a body's parts are level 1)
MAX_DEPTH = 8
#: parts per combination, vertices per polygon (the simplicity check is quadratic in them)
MAX_PARTS = 100
MAX_VERTICES = 1000


def check_part(c: Checker, key: str, t: dict, dim: int, shape: str, depth: int = 0) -> dict:
    """The resolved geometry of a shape named ``shape`` whose table ``t`` was checked for
    unknown keys by the caller: its own keys only (``shape`` first)."""
    if dim not in PART_DIMS[shape]:
        allowed = ", ".join(f'"{s}"' for s, dims in PART_DIMS.items() if dim in dims)
        c.fail(f"{key}.shape", f'expected {allowed} in a {dim}D scene, got "{shape}" '
                               f"(only for dim {' or '.join(map(str, PART_DIMS[shape]))})")
    for name in ALL_PART_KEYS[1:]:
        if name in t and name not in PART_KEYS[shape]:
            c.fail(f"{key}.{name}", f'not used by shape "{shape}" (expected '
                                    f"{' and '.join(PART_KEYS[shape])})")
    if shape in csg.COMBINATORS:
        return {"shape": shape, "parts": _parts(c, key, t, dim, shape, depth)}
    return {"shape": shape, **_PRIMITIVES[shape](c, key, t, dim)}


def _parts(c: Checker, key: str, t: dict, dim: int, shape: str, depth: int) -> list:
    pkey = f"{key}.parts"
    raw = c.required(key, t, "parts", "a list of tables ({shape = ..., ...})")
    if not isinstance(raw, list) or not raw or len(raw) > MAX_PARTS:
        c.expected(pkey, f"a list of 1 to {MAX_PARTS} tables ({{shape = ..., ...}})", raw)
    if depth + 1 > MAX_DEPTH:
        c.fail(pkey, f"combinations nest at most {MAX_DEPTH} deep (a {shape} inside "
                     f"{depth} others)")
    out = []
    for i, item in enumerate(raw):
        ikey = f"{pkey}.{i}"
        p = c.table(ikey, item, ALL_PART_KEYS)
        name = c.choice(f"{ikey}.shape", c.required(ikey, p, "shape", "a shape name"),
                        tuple(PART_DIMS))
        out.append(check_part(c, ikey, p, dim, name, depth + 1))
    if shape == "difference" and out[0]["shape"] == "half_space":
        c.fail(f"{pkey}.0", "expected a bounded first part (a difference keeps what its first "
                            "part holds, and a half_space is unbounded)")
    return out


def _box(c: Checker, key: str, t: dict, dim: int) -> dict:
    pts = f"{dim} numbers"
    bmin = c.vector(f"{key}.min", c.required(key, t, "min", pts), dim, "float", False)
    bmax = c.vector(f"{key}.max", c.required(key, t, "max", pts), dim, "float", False)
    if any(b <= a for a, b in zip(bmin, bmax)):
        c.expected(f"{key}.max", f"each component > {key}.min {show(bmin)}", bmax)
    out: dict[str, Any] = {"min": bmin, "max": bmax}
    if t.get("angle") is not None:
        if dim == 1:
            c.fail(f"{key}.angle", "expected no angle in a 1D scene (nothing to rotate)")
        out["angle"] = c.number(f"{key}.angle", t["angle"],
                                "a number (degrees, counter-clockwise about the box centre)")
    return out


def _round(c: Checker, key: str, t: dict, dim: int) -> dict:
    center = c.vector(f"{key}.center", c.required(key, t, "center", f"{dim} numbers"),
                      dim, "float", False)
    return {"center": center, "radius": _positive(c, key, t, "radius")}


def _cylinder(c: Checker, key: str, t: dict, dim: int) -> dict:
    axis = c.choice(f"{key}.axis", c.required(key, t, "axis", '"x", "y" or "z"'),
                    tuple(AXIS_NAMES[:dim]))
    return {"axis": axis, **_round(c, key, t, dim), "length": _positive(c, key, t, "length")}


def _positive(c: Checker, key: str, t: dict, name: str) -> float:
    return c.number(f"{key}.{name}", c.required(key, t, name, "a number > 0"), "a number > 0",
                    lambda x: x > 0)


def _polygon(c: Checker, key: str, t: dict, dim: int) -> dict:
    vkey = f"{key}.vertices"
    what = f"a list of 3 to {MAX_VERTICES} points [x, y]"
    raw = c.required(key, t, "vertices", what)
    if not isinstance(raw, list) or not 3 <= len(raw) <= MAX_VERTICES:
        c.expected(vkey, what, raw)
    v = [c.vector(f"{vkey}.{i}", p, 2, "float", False) for i, p in enumerate(raw)]
    xs, ys = [p[0] for p in v], [p[1] for p in v]
    span = (max(xs) - min(xs)) * (max(ys) - min(ys))
    area = abs(csg.polygon_area(v))
    if not area > 1e-12 * span:
        c.fail(vkey, f"expected a polygon that encloses an area, got area {area:.3g} "
                     f"({len(v)} vertices; are they all on one line?)")
    crossing = csg.polygon_crossing(v)
    if crossing is not None:
        i, j = crossing
        c.fail(vkey, f"expected a simple polygon (edges meeting only at their shared vertices), "
                     f"but edge {i} ({show(v[i])} to {show(v[(i + 1) % len(v)])}) meets edge "
                     f"{j} ({show(v[j])} to {show(v[(j + 1) % len(v)])})")
    return {"vertices": v}


def _half_space(c: Checker, key: str, t: dict, dim: int) -> dict:
    point = c.vector(f"{key}.point", c.required(key, t, "point", f"{dim} numbers"),
                     dim, "float", False)
    normal = c.vector(f"{key}.normal", c.required(key, t, "normal", f"{dim} numbers"),
                      dim, "float", False)
    if not any(normal):
        c.expected(f"{key}.normal", "a nonzero vector (the outward normal of the plane)", normal)
    return {"point": point, "normal": normal}


_PRIMITIVES = {"box": _box, "disk": _round, "sphere": _round, "cylinder": _cylinder,
               "polygon": _polygon, "half_space": _half_space}


def csg_bounds(c: Checker, key: str, geometry: dict, dim: int) -> tuple[list, list]:
    """The finite bounds of a body's resolved geometry, or a one-line error: unbounded (a
    half_space not cut by a bounded part) or empty (parts that share no space)."""
    lo, hi = csg.bounds(build(Part, geometry), dim)
    shape = geometry["shape"]
    if not all(math.isfinite(v) for v in lo + hi):
        c.fail(f"{key}.parts", f"the {shape} is unbounded (bounds {show(lo)} to {show(hi)}): a "
                               "half_space must be intersected with, or subtracted from, a "
                               "bounded part")
    if any(b <= a for a, b in zip(lo, hi)):
        c.fail(f"{key}.parts", f"the {shape} is empty: its parts share no space (bounds "
                               f"{show(lo)} to {show(hi)})")
    return lo, hi
