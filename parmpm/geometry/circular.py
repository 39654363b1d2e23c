"""Round bodies, however they are written: which shapes are a disk, an annulus, a sphere, a
cylinder or a tube — what decides whether a body can be seeded "conforming", in rings, shells or
extruded rings that follow its outline (:mod:`parmpm.particles.seeding.conforming`; the scene's
``seeding`` key, :mod:`parmpm.scene.bodies`).

:func:`round_form` reads a shape record (``shape`` and its fields, :mod:`parmpm.geometry.csg`):

* a combination of one part (``union``, ``intersection`` or ``difference``) is that part;
* a ``disk`` (2D) or ``sphere`` (3D) is itself, a ``cylinder`` (3D) a tube of inner radius 0;
* a ``difference`` whose first part is a disk and whose others are disks *concentric* with it
  (centres equal to :data:`REL_TOL` of the larger of the outer radius and the centre's largest
  coordinate) and smaller is an **annulus**, its inner radius the largest removed radius: the
  smaller removed disks lie inside that one and remove nothing more;
* a cylinder minus cylinders along the same axis (cross-section centres equal likewise), thinner
  and covering its whole length (each removed one as long or longer, reaching past both ends) is
  a **tube**.

Anything else (a box, a polygon, two disks in a union, a disk minus an off-centre disk, a nested
difference, a hollow sphere) is None: no conforming seeding yet, seeded on the lattice. Pure
Python on the records' fields.
"""
from __future__ import annotations

from dataclasses import dataclass

#: centres (and a tube's ends) agree when they differ by at most this much of the body's size
REL_TOL = 1e-12
AXES = "xyz"


@dataclass(frozen=True)
class Round:
    """A round body: ``kind`` "disk" (2D, an annulus when ``inner`` > 0), "sphere" (3D) or
    "cylinder" (3D, a tube when ``inner`` > 0; ``axis`` its unit direction, ``length`` along
    it, ``center`` its mid-point)."""

    kind: str
    center: tuple[float, ...]
    radius: float
    inner: float = 0.0
    axis: tuple[float, ...] | None = None
    length: float | None = None

    @property
    def name(self) -> str:
        """What it is, in words: disk, annulus, sphere, cylinder or tube."""
        if self.inner > 0.0:
            return {"disk": "annulus", "cylinder": "tube"}[self.kind]
        return self.kind


def round_form(node, dim: int) -> Round | None:
    """The round body ``node`` is (module doc), or None."""
    node = _unwrap(node)
    if node.shape == "disk" and dim == 2 or node.shape == "sphere" and dim == 3:
        return Round(node.shape, _floats(node.center), float(node.radius))
    if node.shape == "cylinder" and dim == 3:
        return _cylinder(node)
    if node.shape != "difference":
        return None
    outer, *removed = (_unwrap(p) for p in node.parts)
    kind = {2: "disk", 3: "cylinder"}[dim] if dim in (2, 3) else None
    if outer.shape != kind or any(p.shape != kind for p in removed):
        return None
    form = Round("disk", _floats(outer.center), float(outer.radius)) if kind == "disk" \
        else _cylinder(outer)
    inner = 0.0
    for part in removed:
        if not _coaxial(form, part) or not float(part.radius) < form.radius:
            return None
        inner = max(inner, float(part.radius))
    return Round(form.kind, form.center, form.radius, inner, form.axis, form.length)


def _unwrap(node):
    """A combination of one part is that part (all the way down)."""
    while node.shape in ("union", "intersection", "difference") and len(node.parts) == 1:
        node = node.parts[0]
    return node


def _floats(v) -> tuple[float, ...]:
    return tuple(float(x) for x in v)


def _cylinder(node) -> Round:
    k = AXES.index(node.axis)
    axis = tuple(1.0 if i == k else 0.0 for i in range(3))
    return Round("cylinder", _floats(node.center), float(node.radius), 0.0, axis,
                 float(node.length))


def _coaxial(form: Round, part) -> bool:
    """``part`` (a disk or cylinder) shares ``form``'s centre (a cylinder: its axis, and it
    covers ``form``'s length), to :data:`REL_TOL` of ``form``'s size."""
    c, p = form.center, _floats(part.center)
    if form.kind == "disk":
        tol = REL_TOL * max(form.radius, *(abs(x) for x in c))
        return all(abs(a - b) <= tol for a, b in zip(c, p))
    k = AXES.index(part.axis)
    if form.axis[k] != 1.0:
        return False
    half, part_half = 0.5 * form.length, 0.5 * float(part.length)
    tol = REL_TOL * max(form.radius, half, *(abs(x) for x in c))
    across = all(abs(c[i] - p[i]) <= tol for i in range(3) if i != k)
    covers = p[k] - part_half <= c[k] - half + tol and p[k] + part_half >= c[k] + half - tol
    return across and covers
