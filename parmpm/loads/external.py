"""External loads on particles: body forces, point loads, tractions and pressure on body faces.

Each load becomes, every step, an acceleration ``f_p / m_p`` per particle, added to the force
P2G maps to the grid (the ``bforce`` rows the manufactured forcing uses too):

* ``body_force``: ``b f(t)`` (m/s²) on every particle of a body (all bodies without ``body``);
* ``point``: ``F f(t)`` (N) on the one particle nearest ``at`` at the start;
* ``traction``: ``t f(t) A₀`` (nominal traction, Pa, on the reference area of the particle's
  faces that lie on the body's surface: the direction and the area stay as they were);
* ``pressure``: ``−p f(t) J F⁻ᵀ N A₀`` (a follower load: Nanson's formula turns the reference
  face ``N A₀`` into the current one, so the pressure stays normal to the deforming surface).

The surface faces are found once, from the seeding: a particle's domain is the box
``x₀ ± r₀`` (columns of ``r₀``), and its face ``±r₀ⱼ`` is on the surface when the lattice point
across it, ``x₀ ± 2 r₀ⱼ``, is not inside the body. So the faces of a body tile its surface the
way its particles tile its volume (a staircase on a curved boundary, whose total ``Σ N A₀``
equals the smooth surface's). ``docs/concepts/loads.md`` derives the forms.

A particle keeps its global id as it moves between patches and ranks, so each load holds the
sorted global ids it acts on (gathered from every rank at set-up; a surface is small) and every
step finds them among the rank's rows by binary search.
"""
from __future__ import annotations

import numpy as np

from parmpm.core.jit import kernel
from parmpm.shapes.cpdi import cofactor

BODY_FORCE, POINT, TRACTION, PRESSURE = 0, 1, 2, 3
KIND_CODES = {"body_force": BODY_FORCE, "point": POINT, "traction": TRACTION,
              "pressure": PRESSURE}


#: how far (degrees) a face's outward normal may turn from a load's ``normal`` and still be
#: selected: a turned box's faces, whose normal the scene writes to a few digits, are in
NORMAL_TOLERANCE_DEG = 1.0


def _faces(dim: int, x0: np.ndarray, r0: np.ndarray, inside, region=None, normal=None):
    """Per face direction ``(j, sign)``: which particles have that face on the surface (inside
    ``region``, facing ``normal`` where given), its outward unit normal (n, d) and area (n,)."""
    n = x0.shape[0]
    for j in range(dim):
        half = r0[:, :, j]                          # (n, d): the half-domain vector along j
        length = np.linalg.norm(half, axis=1)
        # the face's area: the product of the other full domain lengths (orthogonal vectors)
        others = [np.linalg.norm(r0[:, :, k], axis=1) * 2.0 for k in range(dim) if k != j]
        face = np.prod(others, axis=0) if others else np.ones(n)
        unit = half / np.where(length > 0, length, 1.0)[:, None]
        for sign in (1.0, -1.0):
            across = x0 + sign * 2.0 * half
            on = ~inside(across)
            if region is not None:
                centre = x0 + sign * half
                lo, hi = (np.asarray(b, float) for b in region)
                on &= np.all((centre >= lo) & (centre <= hi), axis=1)
            if normal is not None:
                cos = np.cos(np.radians(NORMAL_TOLERANCE_DEG))
                on &= sign * (unit @ np.asarray(normal, float)) >= cos
            yield on, sign * unit, face


def surface_faces(dim: int, x0: np.ndarray, r0: np.ndarray, inside, region=None, normal=None):
    """Per particle (rows of ``x0`` (n, d), ``r0`` (n, d, d)): the sum of its surface faces'
    reference area vectors ``Σ N A₀`` (n, d) and areas ``Σ A₀`` (n,). ``inside(points)`` is the
    body's strict inside test; ``region`` ``(lo, hi)``: only faces whose centre lies in it;
    ``normal`` (unit): only faces whose outward normal is within
    :data:`NORMAL_TOLERANCE_DEG` of it."""
    n = x0.shape[0]
    area_vec = np.zeros((n, dim))
    area = np.zeros(n)
    for on, out, face in _faces(dim, x0, r0, inside, region, normal):
        area_vec[on] += out[on] * face[on, None]
        area[on] += face[on]
    return area_vec, area


def face_directions(dim: int, x0: np.ndarray, r0: np.ndarray, inside, region=None) -> dict:
    """The surface faces :func:`surface_faces` takes, tallied by outward normal: ``{normal
    (rounded to 1e-6): [faces, area]}``: a region that holds more than one direction loads the
    corners' side faces too (issue 41)."""
    out: dict = {}
    for on, unit, face in _faces(dim, x0, r0, inside, region):
        if not np.any(on):
            continue
        keys = np.round(unit[on], 6) + 0.0                  # -0.0 -> 0.0
        uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
        for k, u in enumerate(uniq):
            mask = inverse.reshape(-1) == k
            tally = out.setdefault(tuple(u.tolist()), [0, 0.0])
            tally[0] += int(np.count_nonzero(mask))
            tally[1] += float(face[on][mask].sum())
    return out


class LoadSet:
    """The scene's loads as arrays: per load its kind code, time function, vector (or pressure),
    and the sorted global ids with (for tractions, pressure) each one's ``Σ N A₀`` and ``Σ A₀``."""

    def __init__(self, dim: int):
        self.dim = dim
        self.items = []  # (code, time function, value (3,), gids, area_vec (n, 3), area (n,))

    def add(self, code: int, time, value, gids, area_vec=None, area=None) -> None:
        gids = np.asarray(gids, np.int64)
        order = np.argsort(gids, kind="stable")
        av = np.zeros((gids.size, 3))
        ar = np.zeros(gids.size)
        if area_vec is not None:
            av[:, :self.dim] = np.asarray(area_vec)[order]
            ar[:] = np.asarray(area)[order]
        v = np.zeros(3)
        v[:np.size(value)] = value
        self.items.append((code, time, v, gids[order], av, ar))

    def __bool__(self) -> bool:
        return bool(self.items)

    def __call__(self, t: float, rows, out: np.ndarray) -> None:
        """``out[i]``: the loads' acceleration of physical row ``i`` of ``rows`` at ``t``."""
        out[:] = 0.0
        for code, time, value, gids, av, ar in self.items:
            scale = time.value(t)
            if scale == 0.0 or gids.size == 0:
                continue
            add_load(self.dim, code, scale * value, gids, av, ar, rows.gid, rows.mass, rows.F,
                     out)


@kernel
def add_load(d, code, value, gids, area_vec, area, gid, mass, F, out):
    """Add one load's acceleration to ``out`` for every row whose global id is in ``gids``
    (sorted), or for a body force in ``[gids[0], gids[1])`` (a body's id range)."""
    ng = gids.size
    cof = np.zeros((3, 3))
    for i in range(gid.size):
        g = gid[i]
        if code == BODY_FORCE:
            if g < gids[0] or g >= gids[1]:
                continue
            for a in range(d):
                out[i, a] += value[a]
            continue
        j = np.searchsorted(gids, g)
        if j >= ng or gids[j] != g:
            continue
        m = mass[i]
        if code == POINT:
            for a in range(d):
                out[i, a] += value[a] / m
        elif code == TRACTION:
            for a in range(d):
                out[i, a] += value[a] * area[j] / m
        else:  # pressure: −p J F⁻ᵀ (N A₀) = −p cof(F) (N A₀), value[0] = p
            cofactor(d, F[i], cof)
            for a in range(d):
                acc = 0.0
                for b in range(d):
                    acc += cof[a, b] * area_vec[j, b]
                out[i, a] -= value[0] * acc / m
