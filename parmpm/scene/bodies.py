"""Scene schema, bodies: ``[[bodies]]`` tables — shape, placement (turned boxes), material,
particles per cell and the initial velocity field (uniform, affine, spin, vibration mode).
Cylinders, polygons and CSG bodies (``parts``) are checked by :mod:`parmpm.scene.parts`, bodies
read from a file (``mesh``, ``surface``, ``particles``) by :mod:`parmpm.scene.body_files`.

Split from :mod:`parmpm.scene.schema` (which calls :func:`check_bodies`); the same conventions: every
problem is a one-line ``SceneError`` naming the key, the value and what was expected.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from parmpm.geometry import csg
from parmpm.geometry.circular import round_form
from parmpm.geometry.primitives import rotated_box_bounds
from parmpm.scene.body_files import FILE_DIMS, FILE_KEYS, check_file_body, listed
from parmpm.scene.recorded_files import LISTED_SHAPES, detached
from parmpm.scene.check import AXIS_NAMES, Checker, show
from parmpm.scene.parts import PART_DIMS, PART_KEYS, check_part, csg_bounds
from parmpm.scene.records import Part, build

SHAPE_DIMS = {"box": (1, 2, 3), "disk": (2,), "sphere": (3,),
              **{s: d for s, d in PART_DIMS.items() if s != "half_space"}, **FILE_DIMS}
BODY_KEYS = ("shape", "min", "max", "center", "radius", "material", "ppc", "velocity", "vibration",
             "angular_velocity", "angle", "velocity_gradient", "axis", "length", "vertices",
             "parts", "file", "groups", "split", "step", "file_size", "file_sha256", "seeding")
SHAPE_KEYS = {"box": ("min", "max"), "disk": ("center", "radius"), "sphere": ("center", "radius"),
              **{s: k for s, k in PART_KEYS.items() if s not in ("box", "half_space")},
              **FILE_KEYS}
_SHAPE_ONLY_KEYS = ("min", "max", "center", "radius", "axis", "length", "vertices", "parts",
                    "file", "groups", "split", "step", "file_size", "file_sha256")
#: the key a body outside the grid is blamed on, by shape
_PLACED_BY = {"disk": "center", "sphere": "center", "cylinder": "center", "polygon": "vertices",
              "mesh": "file", "surface": "file", "particles": "file"}
VIBRATION_KEYS = ("amplitude", "mode", "axis")
#: how a body's particles are placed: "conforming" follows a round body's outline (a disk's or
#: annulus's rings, :mod:`parmpm.particles.seeding.polar`; a sphere's shells,
#: :mod:`parmpm.particles.seeding.spherical`; a cylinder's or tube's extruded rings,
#: :mod:`parmpm.particles.seeding.cylindrical`), "lattice" is the grid-aligned lattice it masks
SEEDINGS = ("conforming", "lattice")
#: the shapes that can be seeded to follow their outline: these always, a CSG body when its
#: geometry is one of them (:func:`parmpm.geometry.circular.round_form`: an annulus, a tube)
CONFORMING_SHAPES = ("disk", "sphere", "cylinder")


#: the most particles per cell per axis: beyond it one cell holds more particles than a machine
#: does, and counts overflow the integers arrays are indexed with (the memory check,
#: parmpm.driver.footprint, bounds the whole scene)
MAX_PPC = 1000


def check_bodies(c: Checker, raw: Any, dim: int, grid: dict, materials: dict) -> list:
    if isinstance(raw, dict):
        c.fail("bodies", "expected an array of tables ([[bodies]]), got a single table [bodies]")
    if not isinstance(raw, list) or not raw:
        c.expected("bodies", "at least one [[bodies]] table", raw)
    lo = grid["origin"]
    hi = [o + n * h for o, n, h in zip(lo, grid["cells"], grid["cell_size"])]
    return [_body(c, f"bodies.{i}", spec, dim, lo, hi, grid, materials)
            for i, spec in enumerate(raw)]


def _body(c: Checker, key: str, raw: Any, dim: int, lo: list, hi: list, grid: dict,
          materials: dict) -> dict:
    if isinstance(raw, dict) and raw.get("shape") == "half_space":
        c.fail(f"{key}.shape", 'a half_space is unbounded: use it as one of the parts of an '
                               '"intersection" or "difference" (e.g. to notch a box)')
    t = c.table(key, raw, BODY_KEYS)
    shape = _shape(c, key, t, dim)
    out: dict[str, Any] = {"shape": shape}
    # the material first (as always), unless a particle file may name its own
    material = None if shape == "particles" else _material(c, key, t, out, dim, materials)
    bmin, bmax = _placement(c, key, t, dim, out, materials)
    out["material"] = _material(c, key, t, out, dim, materials) if shape == "particles" else material
    for axis in range(dim):
        tol = 1e-9 * grid["cell_size"][axis]
        below, above = bmin[axis] < lo[axis] - tol, bmax[axis] > hi[axis] + tol
        if below or above:
            side = (("min" if below else "max") if shape == "box"
                    else _PLACED_BY.get(shape, "parts"))
            c.fail(f"{key}.{side}", f"body {key.split('.')[1]} spans [{bmin[axis]!r}, {bmax[axis]!r}] on "
                        f"axis {axis} ({AXIS_NAMES[axis]}), expected it inside the grid "
                        f"[{lo[axis]!r}, {hi[axis]!r}]")
    out["ppc"] = _ppc(c, key, t, dim, shape)
    out["seeding"] = _seeding(c, key, t, out, dim)
    _motion(c, key, t, dim, out)
    return out


def _seeding(c: Checker, key: str, t: dict, out: dict, dim: int) -> str | None:
    """"conforming" (the default where the body is round: :data:`CONFORMING_SHAPES`, or a CSG
    body that is a disk, annulus, sphere, cylinder or tube) or "lattice"; None for a listed
    body (its points are given)."""
    shape = out["shape"]
    if shape in LISTED_SHAPES:
        if t.get("seeding") is not None:
            c.fail(f"{key}.seeding", f'not used by shape "{shape}" (its particles are listed); '
                                     "expected no seeding key")
        return None
    rounded = shape in CONFORMING_SHAPES or shape in csg.COMBINATORS and round_form(
        build(Part, {"shape": shape, "parts": out["parts"]}), dim) is not None
    seeding = c.choice(f"{key}.seeding", t.get("seeding", "conforming" if rounded else "lattice"),
                       SEEDINGS)
    if seeding == "conforming" and not rounded:
        which = ("with these parts " if shape in csg.COMBINATORS else "")
        c.fail(f"{key}.seeding", f'"conforming" is not yet available for shape "{shape}" {which}'
                                 f'(only for {", ".join(CONFORMING_SHAPES)}, and a CSG body that '
                                 "is one of them or a disk or cylinder minus smaller concentric "
                                 'ones: an annulus or a tube); expected "lattice"')
    return seeding


def _material(c: Checker, key: str, t: dict, out: dict, dim: int, materials: dict) -> str | None:
    """The body's material: required, except for a particle file that names its particles'
    (then None: each particle's is the file's, checked by :mod:`parmpm.scene.body_files`)."""
    names = None
    if out["shape"] == "particles":
        view = SimpleNamespace(shape="particles", file=out["file"], step=out["step"],
                               file_sha256=out.get("file_sha256"))
        if detached(view) and t.get("material") is None:
            return None  # a restart without the file: the checkpoint's particles name theirs
        names = None if detached(view) else listed(view, dim).material
    if names is not None:
        if t.get("material") is not None:
            c.fail(f"{key}.material", f"the particle file '{out['file']}' names each particle's "
                                      f"material, so {show(t['material'])} would be ignored; "
                                      "expected no material key (or a file without materials)")
        return None
    material = c.string(f"{key}.material", c.required(key, t, "material", "a material name"))
    if material not in materials:
        c.fail(f"{key}.material", f"unknown material {show(material)} (defined: "
                                  + ", ".join(show(m) for m in materials) + ")")
    return material


def _ppc(c: Checker, key: str, t: dict, dim: int, shape: str) -> list | None:
    """Particles per cell per axis; None for a mesh or particle body (its points are listed)."""
    if shape in LISTED_SHAPES:
        if t.get("ppc") is not None:
            why = ("one per quadrature point of each element: use split to refine"
                   if shape == "mesh" else "one per row of the file")
            c.fail(f"{key}.ppc", f'not used by shape "{shape}" (its particles are {why}); '
                                 "expected no ppc key")
        return None
    ppc = c.vector(f"{key}.ppc", t.get("ppc", 2), dim, "int>0")
    if max(ppc) > MAX_PPC:
        c.expected(f"{key}.ppc", f"integers from 1 to {MAX_PPC} (particles per cell per axis)",
                   t.get("ppc"))
    return ppc


def _shape(c: Checker, key: str, t: dict, dim: int) -> str:
    """The body's shape, allowed in ``dim`` dimensions, with only its own placement keys."""
    shape = c.choice(f"{key}.shape", t.get("shape", "box"), tuple(SHAPE_DIMS))
    if dim not in SHAPE_DIMS[shape]:
        allowed = ", ".join(f'"{s}"' for s, dims in SHAPE_DIMS.items() if dim in dims)
        c.fail(f"{key}.shape", f'expected {allowed} in a {dim}D scene, got "{shape}" '
                               f"(only for dim {' or '.join(map(str, SHAPE_DIMS[shape]))})")
    for name in _SHAPE_ONLY_KEYS:
        if name in t and name not in SHAPE_KEYS[shape]:
            c.fail(f"{key}.{name}", f'not used by shape "{shape}" (expected '
                                    f"{' and '.join(SHAPE_KEYS[shape])})")
    return shape


def _placement(c: Checker, key: str, t: dict, dim: int, out: dict,
               materials: dict) -> tuple[list, list]:
    """Into ``out``: a box's ``min``, ``max`` and ``angle``, a disk's or sphere's ``angle``
    (None), ``center`` and ``radius``, or another shape's keys (:func:`parmpm.scene.parts.check_part`)
    and ``angle`` (None). Returns the bounding box that must fit in the grid."""
    shape = out["shape"]
    if shape == "box":
        pts = f"{dim} numbers"
        bmin = c.vector(f"{key}.min", c.required(key, t, "min", pts), dim, "float", False)
        bmax = c.vector(f"{key}.max", c.required(key, t, "max", pts), dim, "float", False)
        if any(b <= a for a, b in zip(bmin, bmax)):
            c.expected(f"{key}.max", f"each component > {key}.min {show(bmin)}", bmax)
        out.update(min=bmin, max=bmax)
        out["angle"] = _angle(c, f"{key}.angle", t.get("angle"), dim)
        if out["angle"]:  # the rotated box's bounding box is what must fit in the grid
            return rotated_box_bounds(bmin, bmax, out["angle"])
        return bmin, bmax
    if t.get("angle") is not None:
        why = ("looks the same at every angle" if shape in ("disk", "sphere") else
               "is placed by its own coordinates: turn those")
        c.fail(f"{key}.angle", f'expected only on shape "box" (a {shape} {why}), got shape '
                               + show(shape))
    if shape in FILE_DIMS:  # read from a file: its path and keys
        geometry, lo, hi = check_file_body(c, key, t, dim, shape, materials)
        out.update(geometry)
        out["angle"] = None
        return lo, hi
    if shape not in ("disk", "sphere"):  # a cylinder, polygon or CSG body: its own keys
        geometry = check_part(c, key, t, dim, shape)
        out.update(geometry)
        out["angle"] = None
        return csg_bounds(c, key, geometry, dim)
    out["angle"] = None
    center = c.vector(f"{key}.center", c.required(key, t, "center", f"{dim} numbers"),
                      dim, "float", False)
    radius = c.number(f"{key}.radius", c.required(key, t, "radius", "a number > 0"),
                      "a number > 0", lambda x: x > 0)
    out.update(center=center, radius=radius)
    return [x - radius for x in center], [x + radius for x in center]


def _motion(c: Checker, key: str, t: dict, dim: int, out: dict) -> None:
    """Into ``out``: the initial ``velocity``, ``angular_velocity``, ``velocity_gradient`` and
    ``vibration`` (a box's mode)."""
    out["velocity"] = c.vector(f"{key}.velocity", t.get("velocity", [0.0] * dim), dim, "float",
                               False)
    out["angular_velocity"] = None
    if t.get("angular_velocity") is not None:
        akey = f"{key}.angular_velocity"
        if dim == 1:
            c.fail(akey, "expected no angular velocity in a 1D scene (nothing to rotate about)")
        if dim == 2:
            out["angular_velocity"] = c.number(akey, t["angular_velocity"],
                                               "a number (rad/s, counter-clockwise)")
        else:
            out["angular_velocity"] = c.vector(akey, t["angular_velocity"], 3, "float", False)
    out["velocity_gradient"] = _velocity_gradient(c, f"{key}.velocity_gradient",
                                                  t.get("velocity_gradient"), dim)
    out["vibration"] = None
    if t.get("vibration") is not None:
        vkey = f"{key}.vibration"
        v = c.table(vkey, t["vibration"], VIBRATION_KEYS)
        if out["shape"] != "box":
            c.fail(vkey, f'expected only on shape "box", got shape "{out["shape"]}"')
        out["vibration"] = {
            "amplitude": c.number(f"{vkey}.amplitude",
                                  c.required(vkey, v, "amplitude", "a number (velocity)")),
            "mode": c.integer(f"{vkey}.mode", v.get("mode", 1), "an integer >= 1",
                              lambda n: n >= 1),
            "axis": c.integer(f"{vkey}.axis", v.get("axis", 0),
                              f"an integer in [0, {dim})", lambda a: 0 <= a < dim),
        }


def _angle(c: Checker, key: str, raw: Any, dim: int) -> float | None:
    """A box's rotation about its centre in the x-y plane (degrees, counter-clockwise)."""
    if raw is None:
        return None
    if dim == 1:
        c.fail(key, "expected no angle in a 1D scene (nothing to rotate)")
    return c.number(key, raw, "a number (degrees, counter-clockwise about the box centre)")


def _velocity_gradient(c: Checker, key: str, raw: Any, dim: int) -> list | None:
    """``L`` of the initial affine velocity ``v += L·(x − centre)`` (rows: velocity components)."""
    if raw is None:
        return None
    what = f"a {dim}x{dim} matrix (a list of {dim} rows of {dim} numbers, 1/s)"
    if dim == 1 and not isinstance(raw, list):
        raw = [[raw]]
    if dim == 1 and isinstance(raw, list) and raw and not isinstance(raw[0], list):
        raw = [raw]
    if not isinstance(raw, list) or len(raw) != dim:
        c.expected(key, what, raw)
    rows = []
    for row in raw:
        if not isinstance(row, list) or len(row) != dim:
            c.expected(key, what, raw)
        rows.append(c.vector(key, row, dim, "float", False))
    return rows
