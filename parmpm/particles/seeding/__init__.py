"""Seeding: the particles every body starts with, built block by block, kept only where a rank
needs them.

Every rank seeds the same particles (global ids = seeding order, body by body, axis 0 fastest)
but never holds them all: a body is a description (:class:`_Lattice`, :class:`_Turned`,
:func:`_ball`) whose points are made one block of :data:`BLOCK` lattice points at a time.
Set-up (:mod:`parmpm.driver.set_up`) makes two passes over the blocks — the particles per patch
(:meth:`Seeds.patch_counts`), then, once the patches are dealt out, the global ids in this
rank's patches (:meth:`Seeds.members`) — and builds a full :class:`parmpm.particles.store.Particles`
only for those (:meth:`Seeds.particles`). A rank's peak is one block plus its own particles.

An unturned box is counted per axis: the particles per patch are products of per-axis counts,
so :meth:`Seeds.patch_counts` never makes a point. A turned box is its lattice turned about the
box centre, block by block; its blocks start at multiples of :data:`ALIGN` and a last one shorter
than that joins the one before, so each point comes out of the same BLAS call position as when
the whole body was turned at once (the same bits). On the lattice, a disk or sphere is its box's
lattice masked by the ball, block by block (elementwise: the same bits on any block); a
cylinder, polygon or CSG body (:class:`_Masked`) the same lattice filtered by its inside test
(:func:`parmpm.geometry.csg.inside`; a surface body the winding number's), its particle volume
the spacing's product as a disk's. A round body seeded "conforming" (the default where the
geometry allows, :mod:`parmpm.particles.seeding.conforming`) follows its outline instead, each
particle its cell's exact area or volume and domain: a disk or annulus (a CSG disk minus
concentric disks) in rings (:mod:`~parmpm.particles.seeding.polar`), a sphere in shells
(:mod:`~parmpm.particles.seeding.spherical`), a cylinder or tube in rings extruded in layers
(:mod:`~parmpm.particles.seeding.cylindrical`). A mesh or particle-file body is listed point by
point, each with its own volume (:mod:`parmpm.particles.seeding.listed`).

The initial velocity field a body's particles start with is
:mod:`parmpm.particles.seeding.velocity`.
"""
from __future__ import annotations

import numpy as np

from decomposition.boxes import patch_of_coordinate
from parmpm.core.errors import SceneError, SimulationError
from parmpm.geometry.primitives import turn as rotation
from parmpm.particles.locate import locate_patches
from parmpm.particles.seeding.conforming import CONFORMING, conforming_seeds
from parmpm.particles.seeding.listed import Listed, Share, fill, listed_seeds
from parmpm.particles.seeding.velocity import _initial_affine, _initial_velocity
from parmpm.particles.store import Particles
from parmpm.shapes.cpdi2 import affine_corners
from parmpm.transfer.reach import fmt_vec

#: lattice points per block (a multiple of ALIGN)
BLOCK = 1 << 16
#: block starts are multiples of this; a last block shorter than it joins the one before
ALIGN = 16


class RowWatch:
    """Debug counter: the most particle rows (positions, patch ids, masks, global ids) that one
    array built by seeding held since :meth:`reset` — what the set-up memory tests bound by
    ``own particles + BLOCK + ALIGN``."""

    def __init__(self):
        self.largest = 0

    def reset(self) -> None:
        self.largest = 0

    def note(self, rows: int) -> None:
        self.largest = max(self.largest, int(rows))


WATCH = RowWatch()


def _block_edges(n: int) -> np.ndarray:
    """Start of every block of ``n`` lattice points, then ``n``: multiples of BLOCK, a last
    block shorter than ALIGN joined to the one before."""
    if BLOCK % ALIGN:
        raise ValueError(f"seeding.BLOCK ({BLOCK}) must be a multiple of ALIGN ({ALIGN})")
    edges = list(range(0, n, BLOCK)) + [n]
    if len(edges) > 2 and edges[-1] - edges[-2] < ALIGN:
        del edges[-2]
    return np.asarray(edges, np.int64)


class _Lattice:
    """An unturned box's lattice: cell-centred points ``lo + (i + ½)·spacing`` per axis,
    axis 0 fastest (as :func:`_lattice` orders them), made only for the ids asked for."""

    def __init__(self, lo, spacing, count):
        self.axes = [lo[k] + (np.arange(n) + 0.5) * spacing[k] for k, n in enumerate(count)]
        self.shape = tuple(int(n) for n in count)
        self.n = int(np.prod(self.shape))
        self.firsts = _block_edges(self.n)  # blocks: ids = lattice indices

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, ids) -> np.ndarray:
        ids = np.asarray(ids, np.int64)
        WATCH.note(ids.size)
        idx = np.unravel_index(ids, self.shape, order="F")
        return np.stack([axis[i] for axis, i in zip(self.axes, idx)], axis=1)

    def points(self, ids) -> np.ndarray:
        return self[ids]

    def span(self, a: int, b: int) -> np.ndarray:
        """The points of lattice indices ``a ≤ i < b``."""
        return self[np.arange(a, b)]

    def block(self, j: int) -> np.ndarray:
        return self.span(self.firsts[j], self.firsts[j + 1])

    def full(self) -> np.ndarray:
        return self[np.arange(self.n)]


class _Turned:
    """A box's lattice turned by ``turn`` about the box centre ``mid``, block by block."""

    def __init__(self, lattice: _Lattice, mid: np.ndarray, turn: np.ndarray):
        self.lattice, self.mid, self.turn = lattice, mid, turn
        self.n = lattice.n
        self.firsts = lattice.firsts

    def __len__(self) -> int:
        return self.n

    def block(self, j: int) -> np.ndarray:
        return (self.lattice.block(j) - self.mid) @ self.turn.T + self.mid

    def points(self, ids) -> np.ndarray:
        return _points_by_block(self, ids)


class _Masked:
    """A shape that is not a box: the points of its bounding box's lattice that ``inside`` keeps,
    in lattice order; one counting pass keeps the first id of every block."""

    def __init__(self, lattice: _Lattice, inside):
        self.lattice, self.inside = lattice, inside
        kept = [self.block(j).shape[0] for j in range(lattice.firsts.size - 1)]
        self.firsts = np.concatenate([[0], np.cumsum(kept)]).astype(np.int64)
        self.n = int(self.firsts[-1])

    def __len__(self) -> int:
        return self.n

    def block(self, j: int) -> np.ndarray:
        pts = self.lattice.block(j)
        return pts[self.inside(pts)]

    def points(self, ids) -> np.ndarray:
        return _points_by_block(self, ids)


def _ball(lattice: _Lattice, centre: np.ndarray, radius: float) -> _Masked:
    """A disk or sphere: the points of its bounding box's lattice within ``radius`` of ``centre``
    (the surface included), in lattice order."""
    r2 = radius * radius
    return _Masked(lattice, lambda pts: np.sum((pts - centre) ** 2, axis=1) <= r2)


def _points_by_block(src, ids) -> np.ndarray:
    """Points ``ids`` (increasing) of a body made block by block: only the blocks holding some."""
    ids = np.asarray(ids, np.int64)
    WATCH.note(ids.size)
    out = np.empty((ids.size, len(src.lattice.shape)))
    cut = np.searchsorted(ids, src.firsts)
    for j in np.flatnonzero(np.diff(cut)):
        s = slice(cut[j], cut[j + 1])
        out[s] = src.block(j)[ids[s] - src.firsts[j]]
    return out


def _blocks(src):
    """(first id, points) of every block of a body, in id order."""
    for j in range(src.firsts.size - 1):
        yield int(src.firsts[j]), src.block(j)


def _lattice(lo, hi, spacing):
    """Cell-centred lattice points of a box, axis 0 fastest."""
    axes = [lo[k] + (np.arange(n) + 0.5) * spacing[k]
            for k, n in enumerate(np.round((np.asarray(hi) - lo) / spacing).astype(int))]
    mesh = np.meshgrid(*axes[::-1], indexing="ij")
    return np.stack([m.ravel() for m in mesh[::-1]], axis=1)


class Seeds:
    """The particles every body seeds: per body (``chunks``) its points' description and the
    per-body constants. Every rank seeds the same (global ids = seeding order) but makes the
    points one block at a time and builds a full :class:`Particles` (velocities included) only
    for the ones it keeps (:meth:`particles`).

    ``motion``: None, or a function of reference positions ``X`` (n, dim) giving the positions
    the particles start at (the manufactured solution starts displaced): patches are found
    from those."""

    def __init__(self, dim: int, chunks: list, material_rows: dict | None = None):
        self.dim = dim
        self.material_rows = dict(material_rows or {})  # name -> row of the material table
        # (points: _Lattice | _Turned | _Masked | Rings | Shells | Tube | Listed, body, spacing
        #  (None: listed; a mean cell's for the CONFORMING ones),
        #  material row (-1: per particle, the file's), turn or None)
        self.chunks = chunks
        self.n = sum(len(c[0]) for c in chunks)
        self.motion = None

    @property
    def x(self) -> np.ndarray:
        """Every seed's reference position, in seeding order (a one-rank convenience: set-up
        never makes it)."""
        parts = [np.concatenate([b for _, b in _blocks(c[0])]) for c in self.chunks]
        WATCH.note(self.n)
        return np.concatenate(parts) if parts else np.zeros((0, self.dim))

    def _separable(self, src) -> bool:
        """An unturned box starting on its seeds: patch membership factorises by axis."""
        return isinstance(src, _Lattice) and self.motion is None

    @staticmethod
    def _axis_patches(lat: _Lattice, disc):
        """Per axis, the patch index of every lattice coordinate — the same
        :func:`~decomposition.boxes.patch_of_coordinate` as
        :func:`parmpm.particles.locate.locate_patches`, on the same ``(x − origin)·(1/h)`` — or None if
        one lies outside the grid."""
        lay = disc.layout
        per_axis = []
        for k, axis in enumerate(lat.axes):
            o, ih = float(disc.origin3[k]), float(disc.inv_h3[k])
            cells, ps = int(lay.cells3[k]), int(lay.psize3[k])
            q = np.array([patch_of_coordinate((float(c) - o) * ih, cells, ps, 1.0 / ps)
                          for c in axis], np.int64)
            if q.size and q.min() < 0:
                return None
            per_axis.append(q)
        return per_axis

    @staticmethod
    def _ppa(disc) -> list[int]:
        return [int(n) for n in disc.layout.patches_per_axis]  # padded axes: 1

    def locate(self, disc, pts: np.ndarray, first: int) -> np.ndarray:
        """Flat patch id of the block ``pts`` (global ids from ``first``) where the particles
        start; a particle outside the grid is an error naming it."""
        x = pts if self.motion is None else self.motion(pts)
        lay = disc.layout
        where = np.zeros(x.shape[0], np.int64)
        WATCH.note(where.size)
        bad, _ = locate_patches(self.dim, x, disc.origin3, disc.inv_h3, lay.cells3, lay.psize3,
                                lay.patches_per_axis, where, where)
        if bad >= 0:
            raise SimulationError(f"particle {first + bad} at {fmt_vec(x[bad])} is outside the grid")
        return where

    def patch_counts(self, disc) -> np.ndarray:
        """Particles in every patch of the layout (flat ids): unturned boxes from per-axis
        counts, other bodies block by block, a rank's :class:`Share` not at all (rank 0 counts
        a listed body). A particle outside the grid is an error."""
        counts = np.zeros(disc.layout.n_patches, np.int64)
        ppa = self._ppa(disc)
        first = 0
        for src, *_ in self.chunks:
            if isinstance(src, Share):  # rank 0 counts a listed body's (driver.listed_share)
                first += len(src)
                continue
            per_axis = self._axis_patches(src, disc) if self._separable(src) else None
            if per_axis is not None:
                hist = [np.bincount(q, minlength=n) for q, n in zip(per_axis, ppa)]
                hist += [np.ones(1, np.int64)] * (3 - len(hist))
                counts += np.einsum("k,j,i->kji", hist[2], hist[1], hist[0]).ravel()
            else:
                for start, pts in _blocks(src):
                    counts += np.bincount(self.locate(disc, pts, first + start),
                                          minlength=counts.size)
            first += len(src)
        return counts

    def patches_of(self, k: int, disc) -> np.ndarray:
        """Flat patch id of every seed of body ``k``, block by block (rank 0 dealing a listed
        body's rows out: :mod:`parmpm.driver.listed_share`)."""
        first = sum(len(c[0]) for c in self.chunks[:k])
        parts = [self.locate(disc, pts, first + start) for start, pts in _blocks(self.chunks[k][0])]
        return np.concatenate(parts) if parts else np.zeros(0, np.int64)

    def members(self, disc, owned: np.ndarray) -> np.ndarray:
        """Global ids (increasing) of the particles in the patches where ``owned`` (a bool per
        flat patch id) is true, block by block (a :class:`Share`: the ones it holds)."""
        owned = np.asarray(owned, bool)
        out, first = [], 0
        for src, *_ in self.chunks:
            if isinstance(src, Share):  # rank 0 sent this rank exactly its own
                out.append(src.held + first)
                first += len(src)
                continue
            per_axis = self._axis_patches(src, disc) if self._separable(src) else None
            if per_axis is not None:  # per-axis patch indices of the lattice's own points
                ppa = self._ppa(disc)
                for j in range(src.firsts.size - 1):
                    a, b = src.firsts[j], src.firsts[j + 1]
                    idx = np.unravel_index(np.arange(a, b), src.shape, order="F")
                    pid = np.zeros(b - a, np.int64)
                    for k in reversed(range(len(per_axis))):  # flat id, axis 0 fastest
                        pid = pid * ppa[k] + per_axis[k][idx[k]]
                    WATCH.note(pid.size)
                    out.append(np.flatnonzero(owned[pid]) + (first + a))
            else:
                for start, pts in _blocks(src):
                    where = self.locate(disc, pts, first + start)
                    out.append(np.flatnonzero(owned[where]) + (first + start))
            first += len(src)
        mine = np.concatenate(out) if out else np.zeros(0, np.int64)
        WATCH.note(mine.size)
        return mine

    def mass(self, params: np.ndarray) -> np.ndarray:
        """Every particle's mass (a one-rank convenience)."""
        WATCH.note(self.n)
        def body_mass(src, spacing, row):
            if isinstance(src, Listed):
                return params[src.material_rows(np.arange(len(src)), row), 1] * src.vol
            if isinstance(src, CONFORMING):
                return params[row, 1] * src.domains(np.arange(len(src)))[0]
            return np.full(len(src), params[row, 1] * np.prod(spacing))

        return np.concatenate([body_mass(c[0], c[2], c[3]) for c in self.chunks])

    def particles(self, params: np.ndarray, keep: np.ndarray | None = None,
                  optional: tuple[str, ...] = ()) -> Particles:
        """The particles of global ids ``keep`` (increasing; default all), fields filled;
        ``optional``: the optional fields to carry (:data:`parmpm.particles.store.OPTIONAL_FIELDS`)."""
        keep = np.arange(self.n) if keep is None else np.asarray(keep, np.int64)
        WATCH.note(keep.size)
        P = Particles(self.dim, keep.size, optional)
        P.gid[:] = keep
        first = 0
        for src, body, spacing, row, turn in self.chunks:
            lo, hi = np.searchsorted(keep, [first, first + len(src)])
            s, ids = slice(lo, hi), keep[lo:hi] - first
            if isinstance(src, Listed):  # its own volumes, materials, velocities, F
                fill(P, s, src, ids, body, row, params, P.optional)
                if "corners" in P.optional:
                    P.corners[s] = affine_corners(P.F[s], P.r0[s])
                first += len(src)
                continue
            pts = src.points(ids)
            P.x[s] = pts
            P.x0[s] = pts
            P.v[s] = _initial_velocity(self.dim, body, pts)
            if "affine" in P.optional:
                P.affine[s] = _initial_affine(self.dim, body, pts)
            if isinstance(src, CONFORMING):  # each cell its own area and domain
                vol, P.lh0[s], P.r0[s] = src.domains(ids)
                P.vol0[s] = vol
                P.mass[s] = params[row, 1] * vol
            else:
                P.vol0[s] = np.prod(spacing)
                P.mass[s] = params[row, 1] * np.prod(spacing)
                P.lh0[s] = 0.5 * spacing
                P.r0[s] = np.diag(0.5 * spacing) if turn is None else turn * (0.5 * spacing)
            P.mat[s] = row
            if "corners" in P.optional:  # CPDI2: the corners of the domain R0 (F = I)
                P.corners[s] = affine_corners(P.F[s], P.r0[s])
            first += len(src)
        return P


def fmt_spacing(spacing) -> str:
    return ", ".join(f"{float(v):.4g}" for v in np.ravel(spacing))


def seed_bodies(grid, bodies, material_rows: dict[str, int],
                read_listed: tuple[str, ...] = ("mesh", "particles")) -> Seeds:
    """Every body's seeds: ``ppc`` per cell per axis, domains tiling the body (descriptions:
    the points are made block by block when asked for). ``grid``, ``bodies``: the scene's
    records (``scene.spec.grid``, ``scene.spec.bodies``); ``material_rows``: material name →
    its row of the material table; ``read_listed``: the listed shapes (``mesh``, ``particles``)
    whose files are read here; another's seeds are a :class:`Share` awaiting its rows (a
    parallel run: :mod:`parmpm.driver.listed_share`, :mod:`parmpm.driver.mesh_slices`)."""
    d = len(grid.cells)
    h = np.asarray(grid.cell_size, float)
    origin = np.asarray(grid.origin, float)
    chunks = []
    for k, body in enumerate(bodies):
        ppc = None if body.ppc is None else np.asarray(body.ppc, float)
        turn = None
        if body.shape == "box":
            lo, hi = np.asarray(body.min, float), np.asarray(body.max, float)
            count = np.maximum(1, np.round((hi - lo) / h * ppc)).astype(int)
            spacing = (hi - lo) / count
            pts = _Lattice(lo, spacing, count)
            if body.angle:  # the lattice turned about the box centre, domains with it
                turn = rotation(d, body.angle)
                pts = _Turned(pts, 0.5 * (lo + hi), turn)
        elif body.seeding == "conforming":  # rings, shells, extruded rings: outline followed
            pts = conforming_seeds(f"bodies.{k}", body, h, _block_edges)
            spacing = pts.mean_spacing()
        elif body.shape in ("disk", "sphere"):  # on a grid-aligned lattice
            c, r = np.asarray(body.center, float), float(body.radius)
            spacing = h / ppc
            pts = _ball(_grid_lattice(origin, spacing, c - r, c + r), c, r)
            if not len(pts):
                raise SceneError(f"bodies.{k}: a {body.shape} of radius {r:g} m holds no point "
                                 f"of its particle lattice (spacing {fmt_spacing(spacing)} m); "
                                 "enlarge the radius or raise ppc")
        elif body.shape in ("mesh", "particles"):  # listed, each point its own volume
            spacing = None
            pts = (listed_seeds(body, d, material_rows, _block_edges)
                   if body.shape in read_listed else Share.awaiting(body.count(), d))
        else:  # cylinder, polygon, CSG, surface: the same lattice, kept where the body is
            spacing = h / ppc
            bmin, bmax = (np.asarray(b, float) for b in body.bounds())
            pts = _Masked(_grid_lattice(origin, spacing, bmin, bmax),
                          lambda x, body=body: body.inside(d, x))
            if not len(pts):
                why = ("it is thinner than a spacing; raise ppc or refine the grid"
                       if body.shape == "surface" else
                       "its parts leave nothing (a difference that removes all, an intersection "
                       "of parts that do not meet) or less than a spacing; check its parts or "
                       "raise ppc")
                raise SceneError(f"bodies.{k}: the {body.shape} holds no point of its particle "
                                 f"lattice (spacing {fmt_spacing(spacing)} m): {why}")
        row = -1 if body.material is None else material_rows[body.material]
        chunks.append((pts, body, spacing, row, turn))
    return Seeds(d, chunks, material_rows)


def _grid_lattice(origin: np.ndarray, spacing: np.ndarray, bmin, bmax) -> _Lattice:
    """The lattice of spacing ``spacing`` anchored at the grid's ``origin`` (points at
    ``origin + (i + ½)·spacing``) that covers the bounds ``bmin``-``bmax``."""
    lo = origin + np.floor((bmin - origin) / spacing) * spacing
    n = np.ceil((bmax - lo) / spacing).astype(int)
    # the bounding lattice's counts as _lattice computes them from its corners
    count = np.round((lo + n * spacing - lo) / spacing).astype(int)
    return _Lattice(lo, spacing, count)


def bodies_to_particles(grid, bodies, material_rows: dict[str, int],
                        params: np.ndarray) -> Particles:
    """Every body's particles (all of them: a one-rank convenience; see :class:`Seeds`)."""
    return seed_bodies(grid, bodies, material_rows).particles(params)
