"""Scene schema: the bodies' initial speeds, checked against what double precision can sum.

A finite velocity can still be too large to run: ``bodies.0.velocity = 1e300`` squares to
infinity in the first kinetic energy, and the run then stopped at step 0 blaming ``time.cfl``
(the energy watch's hint for a blow-up), a key the user never set. The resolved scene is checked
instead: a bound of each body's speed (its velocity, plus the spin and the velocity gradient
across the body, plus a vibration's amplitude) must give a kinetic energy
``½·ρ·s²·V`` (``V``: the body's bounding box; a particle file's: its fastest particle and its
densest material) below :data:`MAX_KINETIC_ENERGY`; otherwise one
line names the body key that contributes most. Pure Python, as :mod:`parmpm.scene.schema` (numpy for a particle file's velocities).
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.scene.check import Checker, show
from parmpm.scene.recorded_files import detached

#: the largest kinetic energy a body may start with (J, or J per m^(3 - dim)): far below the
#: largest double, so that the sums of a run (energies, work over many steps) stay finite
MAX_KINETIC_ENERGY = 1e300


def _norm(values) -> float:
    """Euclidean norm that overflows to inf, never raises."""
    values = values if isinstance(values, tuple) else (values,)
    flat = [abs(v) for row in values for v in (row if isinstance(row, tuple) else (row,))]
    top = max(flat, default=0.0)
    if top == 0.0 or not math.isfinite(top):
        return top
    return top * math.sqrt(sum((v / top) ** 2 for v in flat))


def check_speeds(c: Checker, bodies: list, materials: dict) -> None:
    """Refuse a body whose initial speed gives a kinetic energy past :data:`MAX_KINETIC_ENERGY`
    (or one that overflows), naming the key that contributes most to the speed. ``bodies``,
    ``materials``: their records (:mod:`parmpm.scene.records`)."""
    for k, body in enumerate(bodies):
        lo, hi = body.bounds()
        reach = 0.5 * _norm(tuple(b - a for a, b in zip(lo, hi)))  # centre to a corner
        volume = math.prod(b - a for a, b in zip(lo, hi))
        terms = {"velocity": _norm(body.velocity)}
        if body.angular_velocity is not None:
            terms["angular_velocity"] = _norm(body.angular_velocity) * reach
        if body.velocity_gradient is not None:
            terms["velocity_gradient"] = _norm(body.velocity_gradient) * reach
        if body.vibration is not None:
            terms["vibration.amplitude"] = abs(body.vibration.amplitude)
        rho = _file_terms(body, terms, materials)
        speed = sum(terms.values())
        energy = 0.5 * rho * speed * speed * volume if math.isfinite(speed) else math.inf
        if math.isfinite(energy) and energy <= MAX_KINETIC_ENERGY:
            continue
        name = max(terms, key=lambda t: terms[t])
        key = f"bodies.{k}.{name}"
        value = (body.vibration.amplitude if name == "vibration.amplitude" else
                 f"velocities up to {terms['file']:g} m/s" if name == "file" else getattr(body, name))
        c.fail(key, f"{show(value)} gives body {k} (density {rho:g}) a speed of up to "
                    f"{speed:g} m/s and a kinetic energy of {energy:g} J, more than double "
                    f"precision can sum over a run (at most {MAX_KINETIC_ENERGY:g} J); expected "
                    "a speed of a physical size")


def _file_terms(body, terms: dict, materials: dict) -> float:
    """The density to bound the energy with; a particle file's velocities into ``terms``."""
    if body.shape != "particles":
        return materials[body.material].density
    if detached(body):  # a restart without the file: checked when the run began
        return max(m.density for m in materials.values())
    data = body.listed(len(body.velocity))
    if data.velocity is not None:
        top = float(np.max(np.abs(data.velocity))) if data.velocity.size else 0.0
        terms["file"] = top * math.sqrt(data.velocity.shape[1]) if math.isfinite(top) else top
    names = [body.material] if body.material is not None else np.unique(data.material).tolist()
    return max(materials[str(n)].density for n in names)
