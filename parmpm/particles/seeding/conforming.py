"""Conforming seedings: particles that follow a round body's outline instead of a lattice's steps,
each cell's exact volume and its own domain.

The body's geometry decides (:func:`parmpm.geometry.circular.round_form`: a disk, an annulus, a
sphere, a cylinder or a tube, written as a primitive or as a CSG combination): a disk or annulus is
seeded in rings (:mod:`parmpm.particles.seeding.polar`), a sphere in shells
(:mod:`parmpm.particles.seeding.spherical`), a cylinder or tube in rings extruded in layers
(:mod:`parmpm.particles.seeding.cylindrical`), for the particle spacing
``s = (Π Δx_k/ppc_k)^(1/d)`` (the geometric mean over the axes). A radius, wall or length below
``s/2`` is an error naming the body: the cells would be far smaller than ``s`` (a thin tube's
ring of tiny cells runs to millions), and the lattice would hold no point of it either.
"""
from __future__ import annotations

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.geometry.circular import round_form
from parmpm.particles.seeding.cylindrical import Tube
from parmpm.particles.seeding.polar import Rings
from parmpm.particles.seeding.spherical import Shells

#: the seedings that follow a body's outline, each cell its own volume and domain
CONFORMING = (Rings, Shells, Tube)


def conforming_seeds(key: str, body, h: np.ndarray, edges):
    """The conforming seeding of ``body`` (its scene key ``key``, e.g. "bodies.0") on a grid of
    spacing ``h``; ``edges``: the block starts of ``n`` ids. A body with no round form, or
    thinner than half a spacing, is a SceneError."""
    d = h.size
    form = round_form(body, d)
    if form is None:
        raise SceneError(f'{key}.seeding: "conforming" is not available for this {body.shape} '
                         "(only for a disk, annulus, sphere, cylinder or tube); expected "
                         '"lattice"')
    size = float(np.prod(h / np.asarray(body.ppc, float)) ** (1.0 / d))
    name = form.name
    a = "an" if name == "annulus" else "a"
    sizes = [(f"{a} {name} of radius {form.radius:g} m", form.radius, "enlarge the radius")]
    if form.inner > 0.0:
        sizes.append((f"the wall of {a} {name} ({form.radius:g} m minus {form.inner:g} m)",
                      form.radius - form.inner, "thicken the wall"))
    if form.length is not None:
        sizes.append((f"{a} {name} of length {form.length:g} m", form.length, "lengthen it"))
    for what, extent, fix in sizes:
        if extent < 0.5 * size:
            raise SceneError(f"{key}: {what} is smaller than half its particle spacing "
                             f"({size:.4g} m); {fix} or raise ppc")
    if form.kind == "disk":
        return Rings(form.center, form.radius, size, edges, form.inner)
    if form.kind == "sphere":
        return Shells(form.center, form.radius, size, edges)
    return Tube(form.center, form.axis, form.radius, form.length, size, edges, form.inner)
