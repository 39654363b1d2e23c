"""Seeding: the particles every body starts with, built only where a rank needs them.

Every rank seeds the same particles (global ids = seeding order, body by body, axis 0 fastest)
but builds a full :class:`parmpm.particles.Particles` only for the ones it keeps
(:meth:`Seeds.particles`). An unturned box keeps just its per-axis coordinates
(:class:`_Lattice`): the particles per patch are then products of per-axis counts
(:meth:`Seeds.patch_counts`) and a rank finds its own particles from a per-axis patch index
(:meth:`Seeds.members`), so set-up never holds every particle's position — about 1 byte per
particle of the whole body instead of ``8·dim``. Turned boxes and disks/spheres keep their
points (their patch membership is not separable by axis).
"""
from __future__ import annotations

import math

import numpy as np

from decomposition.boxes import patch_of_coordinate
from parmpm.errors import SceneError
from parmpm.particles import Particles


class _Lattice:
    """An unturned box's lattice: cell-centred points ``lo + (i + ½)·spacing`` per axis,
    axis 0 fastest (as :func:`_lattice` orders them), made only for the ids asked for."""

    def __init__(self, lo, spacing, count):
        self.axes = [lo[k] + (np.arange(n) + 0.5) * spacing[k] for k, n in enumerate(count)]
        self.shape = tuple(int(n) for n in count)
        self.n = int(np.prod(self.shape))

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, ids) -> np.ndarray:
        idx = np.unravel_index(np.asarray(ids, np.int64), self.shape, order="F")
        return np.stack([axis[i] for axis, i in zip(self.axes, idx)], axis=1)

    def full(self) -> np.ndarray:
        return self[np.arange(self.n)]


def _lattice(lo, hi, spacing):
    """Cell-centred lattice points of a box, axis 0 fastest."""
    axes = [lo[k] + (np.arange(n) + 0.5) * spacing[k]
            for k, n in enumerate(np.round((np.asarray(hi) - lo) / spacing).astype(int))]
    mesh = np.meshgrid(*axes[::-1], indexing="ij")
    return np.stack([m.ravel() for m in mesh[::-1]], axis=1)


def _turn(d: int, degrees: float) -> np.ndarray:
    """Rotation by ``degrees`` counter-clockwise in the x-y plane (the identity on z)."""
    a = math.radians(degrees)
    Q = np.eye(d)
    Q[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    return Q


def _initial_velocity(d: int, body: dict, pts: np.ndarray) -> np.ndarray:
    """A body's initial velocity at ``pts``: uniform + affine + spin + vibration mode."""
    vel = np.tile(np.asarray(body["velocity"], float), (len(pts), 1))
    centre = (np.asarray(body["center"], float) if body["shape"] != "box" else
              0.5 * (np.asarray(body["min"], float) + np.asarray(body["max"], float)))
    if body.get("velocity_gradient") is not None:  # affine: v += L·(x − c)
        L = np.asarray(body["velocity_gradient"], float)
        for i in range(d):  # elementwise, not BLAS: the same bits for any subset of the points
            for j in range(d):
                vel[:, i] += L[i, j] * (pts[:, j] - centre[j])
    omega = body.get("angular_velocity")
    if omega is not None:  # rigid spin about the body's centre: v += ω × (x − c)
        r = pts - centre
        if d == 2:
            vel += float(omega) * np.stack([-r[:, 1], r[:, 0]], axis=1)
        else:
            vel += np.cross(np.asarray(omega, float), r)
    vib = body.get("vibration")
    if vib:
        ax = vib["axis"]
        length = body["max"][ax] - body["min"][ax]
        beta = (2 * vib["mode"] - 1) * math.pi / (2 * length)
        vel[:, ax] += vib["amplitude"] * np.sin(beta * (pts[:, ax] - body["min"][ax]))
    return vel


class Seeds:
    """The particles every body seeds, as positions per body (``chunks``) and the per-body
    constants. Every rank seeds the same (global ids = seeding order) but builds a full
    :class:`Particles` (velocities included) only for the ones it keeps (:meth:`particles`): a
    seed costs ``dim`` floats, a particle ~40, so set-up memory per rank follows its own share."""

    def __init__(self, dim: int, chunks: list):
        self.dim = dim
        # (points: an array or a _Lattice, body, spacing, material row, turn or None) per body
        self.chunks = chunks
        self.n = sum(len(c[0]) for c in chunks)

    @property
    def x(self) -> np.ndarray:
        """Every seed's position, in seeding order (made here for lattices)."""
        parts = [c[0].full() if isinstance(c[0], _Lattice) else c[0] for c in self.chunks]
        if len(parts) == 1:
            return parts[0]
        return np.concatenate(parts) if parts else np.zeros((0, self.dim))

    @property
    def separable(self) -> bool:
        """Every body an unturned box: patch membership factorises by axis."""
        return bool(self.chunks) and all(isinstance(c[0], _Lattice) for c in self.chunks)

    def _axis_patches(self, disc):
        """Per body and axis, the patch index of every lattice coordinate — the same
        :func:`~decomposition.boxes.patch_of_coordinate` as
        :func:`parmpm.particles.locate_patches`, on the same ``(x − origin)·(1/h)`` — or None if
        one lies outside the grid."""
        lay = disc.layout
        out = []
        for lat, *_ in self.chunks:
            per_axis = []
            for k, axis in enumerate(lat.axes):
                o, ih = float(disc.origin3[k]), float(disc.inv_h3[k])
                cells, ps = int(lay.cells3[k]), int(lay.psize3[k])
                q = np.array([patch_of_coordinate((float(c) - o) * ih, cells, ps, 1.0 / ps)
                              for c in axis], np.int64)
                if q.size and q.min() < 0:
                    return None
                per_axis.append(q)
            out.append(per_axis)
        return out

    @staticmethod
    def _ppa(disc) -> list[int]:
        return [int(n) for n in disc.layout.patches_per_axis]  # padded axes: 1

    def patch_counts(self, disc) -> np.ndarray | None:
        """Particles in every patch of the layout (flat ids), from per-axis counts; None when
        the bodies are not all unturned boxes or a particle lies outside the grid."""
        if not self.separable:
            return None
        axes = self._axis_patches(disc)
        if axes is None:
            return None
        ppa = self._ppa(disc)
        counts = np.zeros(ppa[::-1], np.int64)  # indexed [q2, q1, q0]: flat id q0 fastest
        for per_axis in axes:
            hist = [np.bincount(q, minlength=n) for q, n in zip(per_axis, ppa)]
            hist += [np.ones(1, np.int64)] * (3 - len(hist))
            counts += np.einsum("k,j,i->kji", hist[2], hist[1], hist[0])
        return counts.ravel()

    def members(self, disc, owned: np.ndarray) -> np.ndarray:
        """Global ids (increasing) of the particles in the patches where ``owned`` (a bool per
        flat patch id) is true; for seeds that :meth:`patch_counts` could count."""
        own = np.asarray(owned, bool).reshape(self._ppa(disc)[::-1])  # [q2, q1, q0]
        out, first = [], 0
        for (lat, *_), per_axis in zip(self.chunks, self._axis_patches(disc)):
            q = per_axis + [np.zeros(1, np.int64)] * (3 - len(per_axis))
            mask = own[np.ix_(q[2], q[1], q[0])]  # [i2, i1, i0]: raveled, i0 fastest = id order
            out.append(np.flatnonzero(mask.ravel()) + first)
            first += len(lat)
        return np.concatenate(out) if out else np.zeros(0, np.int64)

    def mass(self, params: np.ndarray) -> np.ndarray:
        return np.concatenate([np.full(len(c[0]), params[c[3], 1] * np.prod(c[2]))
                               for c in self.chunks])

    def particles(self, params: np.ndarray, keep: np.ndarray | None = None) -> Particles:
        """The particles of global ids ``keep`` (increasing; default all), fields filled."""
        keep = np.arange(self.n) if keep is None else np.asarray(keep, np.int64)
        P = Particles(self.dim, keep.size)
        P.gid[:] = keep
        first = 0
        for pts, body, spacing, row, turn in self.chunks:  # pts: an array or a _Lattice
            lo, hi = np.searchsorted(keep, [first, first + len(pts)])
            s, ids = slice(lo, hi), keep[lo:hi] - first
            P.x[s] = pts[ids]
            P.x0[s] = pts[ids]
            P.v[s] = _initial_velocity(self.dim, body, pts[ids])
            P.vol0[s] = np.prod(spacing)
            P.mass[s] = params[row, 1] * np.prod(spacing)
            P.mat[s] = row
            P.lh0[s] = 0.5 * spacing
            P.r0[s] = np.diag(0.5 * spacing) if turn is None else turn * (0.5 * spacing)
            first += len(pts)
        return P


def fmt_spacing(spacing) -> str:
    return ", ".join(f"{float(v):.4g}" for v in np.ravel(spacing))


def seed_bodies(scene: dict, material_rows: dict[str, int]) -> Seeds:
    """Seed every body: ``ppc`` per cell per axis, domains tiling the body."""
    d = scene["dim"]
    h = np.asarray(scene["grid"]["cell_size"], float)
    origin = np.asarray(scene["grid"]["origin"], float)
    chunks = []
    for k, body in enumerate(scene["bodies"]):
        ppc = np.asarray(body["ppc"], float)
        turn = None
        if body["shape"] == "box":
            lo, hi = np.asarray(body["min"], float), np.asarray(body["max"], float)
            count = np.maximum(1, np.round((hi - lo) / h * ppc)).astype(int)
            spacing = (hi - lo) / count
            pts = _Lattice(lo, spacing, count)
            if body.get("angle"):  # the lattice turned about the box centre, domains with it
                turn = _turn(d, body["angle"])
                mid = 0.5 * (lo + hi)
                pts = (pts.full() - mid) @ turn.T + mid
        else:  # disk / sphere on a grid-aligned lattice
            c, r = np.asarray(body["center"], float), float(body["radius"])
            spacing = h / ppc
            lo = origin + np.floor((c - r - origin) / spacing) * spacing
            n = np.ceil((c + r - lo) / spacing).astype(int)
            pts = _lattice(lo, lo + n * spacing, spacing)
            pts = pts[np.sum((pts - c) ** 2, axis=1) <= r * r]
            if not len(pts):
                raise SceneError(f"bodies.{k}: a {body['shape']} of radius {r:g} m holds no point "
                                 f"of its particle lattice (spacing {fmt_spacing(spacing)} m); "
                                 "enlarge the radius or raise ppc")
        chunks.append((pts, body, spacing, material_rows[body["material"]], turn))
    return Seeds(d, chunks)


def bodies_to_particles(scene: dict, material_rows: dict[str, int], params: np.ndarray) -> Particles:
    """Every body's particles (all of them: a one-rank convenience; see :class:`Seeds`)."""
    return seed_bodies(scene, material_rows).particles(params)


