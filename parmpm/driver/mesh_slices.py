"""Mesh bodies on several ranks: each rank makes the particles of its own slice of the elements.

Making a mesh body's particles (:func:`parmpm.geometry.mesh.element_particles`: every element's
quadrature points, their volumes and the element checks) is the O(N) part of its set-up; reading
the file is not (a 500² quad mesh: 0.06 s to read, 0.6 s to make its 10⁶ particles, on this
project's machine). So on several ranks rank 0, which read the mesh when it resolved the scene
(:func:`parmpm.scene.agreement.load_shared_scene`, its element checks left to here), deals every
rank a contiguous slice of the elements — those whose particles fall in
``[r·n/P, (r+1)·n/P)`` of the body's ``n``, with the nodes they use — one rank after another
(:func:`decomposition.deal_from_root`); each rank makes and checks its slice's particles, finds
their patches, and the per-patch counts are summed over the ranks. Once the patches are dealt out
every particle's row travels to its patch's rank (:func:`decomposition.migrate`) and the body's
seeds become that rank's :class:`parmpm.particles.seeding.listed.Share`, as a particle file's do
(:mod:`parmpm.driver.listed_share`).

The same bits on any number of ranks: every element's particles are computed from its own nodes
alone (renumbered, not changed), so a slice makes exactly the rows one pass would; global ids are
the file's order. A bad element is the lowest rank's line, which is the first bad element's, as
on one rank; a particle outside the grid likewise. Rank 0 holds the file's nodes and connectivity
(tens of bytes per element) and deals them out; the particles (about 310 bytes each once built)
are made, held and sent P ways.
"""
from __future__ import annotations

import numpy as np

from decomposition import deal_from_root, migrate
from parmpm.core.errors import ParmpmError, SceneError
from parmpm.driver.listed_share import raise_lowest
from parmpm.geometry.mesh import element_particles, particles_per_element
from parmpm.particles.seeding import Seeds
from parmpm.particles.seeding.listed import Share
from parmpm.scene.body_files import volume_mesh


def element_ranges(sizes: list[tuple[int, int]], ranks: int) -> list[list[tuple[int, int, int]]]:
    """Per rank, its ``(block, first element, end element)`` slices of blocks of ``sizes``
    ``(elements, particles per element)``: the elements whose first particle lies in
    ``[r·n//P, (r+1)·n//P)`` — contiguous particle ranges, in rank order, covering every element
    once."""
    n = sum(e * q for e, q in sizes)
    cuts = [r * n // ranks for r in range(ranks + 1)]
    out: list[list[tuple[int, int, int]]] = [[] for _ in range(ranks)]
    offset = 0
    for b, (e, q) in enumerate(sizes):
        # element i of this block starts at particle offset + i*q: its rank is the last cut <= that
        first = [min(e, max(0, -(-(c - offset) // q))) for c in cuts]  # the last: e (n's cut)
        for r in range(ranks):
            if first[r + 1] > first[r]:
                out[r].append((b, first[r], first[r + 1]))
        offset += e * q
    return out


class MeshSlices:
    """This rank's particles of every mesh body of ``seeds`` (made by :func:`make_mesh_slices`):
    per body index ``k`` its first global id ``begin`` within the body, positions ``x``,
    volumes ``vol`` and patch ids ``where`` on the layout of ``disc``."""

    def __init__(self, seeds: Seeds, disc):
        self.seeds, self.disc = seeds, disc
        self.bodies: dict[int, dict] = {}
        self.first = np.cumsum([0] + [len(c[0]) for c in seeds.chunks])  # each body's first id

    def __bool__(self) -> bool:
        return bool(self.bodies)

    def local_counts(self, disc) -> np.ndarray:
        """Particles of this rank's slices per patch of ``disc``'s layout (at another patch size
        too: the idle-ranks advice asks)."""
        counts = np.zeros(disc.layout.n_patches, np.int64)
        for k, s in self.bodies.items():
            where = (s["where"] if disc is self.disc
                     else self.seeds.locate(disc, s["x"], int(self.first[k]) + s["begin"]))
            counts += np.bincount(where, minlength=counts.size)
        return counts

    def patch_counts(self, comm, disc) -> np.ndarray:
        """Particles of every rank's slices per patch (collective: summed over the ranks)."""
        return comm.allreduce(self.local_counts(disc))

    def share(self, comm, rank_of: np.ndarray) -> None:
        """Send every particle to its patch's rank (``rank_of``: per flat patch id) and make each
        mesh body's seeds this rank's :class:`Share` (collective)."""
        for k, s in self.bodies.items():
            src, *rest = self.seeds.chunks[k]
            ids = np.arange(s["begin"], s["begin"] + len(s["vol"]), dtype=np.int64)
            got = migrate({"ids": ids, "x": s["x"], "vol": s["vol"]}, rank_of[s["where"]], comm,
                          None)
            order = np.argsort(got["ids"], kind="stable")
            self.seeds.chunks[k] = (Share(len(src), got["ids"][order], got["x"][order],
                                          got["vol"][order]), *rest)
        self.bodies.clear()


def make_mesh_slices(comm, seeds: Seeds, disc, source: str) -> MeshSlices:
    """Every mesh body's particles made P ways (see the module docstring): rank 0 deals the
    elements, each rank makes, checks and locates its slice's particles (collective; a problem
    on any rank — a bad element, a particle outside the grid — is the lowest rank's line on
    every rank; ``source``: the scene's, which a bad element's line names as the scene check
    does)."""
    slices = MeshSlices(seeds, disc)
    for k, (src, body, *_) in enumerate(seeds.chunks):
        if body.shape != "mesh":
            continue
        problem, kind, deal = None, ParmpmError, None
        if comm.Get_rank() == 0:
            try:
                deal = _dealer(volume_mesh(body, seeds.dim), int(body.split), comm.Get_size(),
                               len(src), f"bodies.{k}.file")
            except ParmpmError as exc:
                problem, kind = str(exc), type(exc)
        raise_lowest(comm, problem, kind)
        part = deal_from_root(comm, deal, root=0)
        try:
            made = _made(part, body, k, source)
            made["where"] = seeds.locate(disc, made["x"], int(slices.first[k]) + made["begin"])
        except ParmpmError as exc:
            problem, kind = str(exc), type(exc)
        raise_lowest(comm, problem, kind)
        slices.bodies[k] = made
    return slices


def _dealer(mesh, split: int, ranks: int, n: int, key: str):
    """Rank ``r``'s part of ``mesh``, made when asked for: ``(the body's id of the slice's first
    particle, the file's numbers of the nodes it uses, their coordinates, its pieces (cell type,
    first element, connectivity as the file numbers it))``. ``n``: the particles the scene
    counted when it read the file; another count now is a file changed since (``key`` names it)."""
    sizes = [(len(b.cells), particles_per_element(b.cell_type, split)) for b in mesh.blocks]
    if sum(e * q for e, q in sizes) != n:
        raise SceneError(f"{key}: the mesh made {n} particles when the scene was read and "
                         f"{sum(e * q for e, q in sizes)} now: it changed meanwhile; run again "
                         "with the file left as it is")
    starts = np.cumsum([0] + [e for e, _ in sizes])         # each block's first element
    offsets = np.cumsum([0] + [e * q for e, q in sizes])    # each block's first particle
    ranges = element_ranges(sizes, ranks)

    def part(r: int):
        used = np.zeros(len(mesh.points), bool)
        pieces, begin = [], int(offsets[-1])
        for j, (b, lo, hi) in enumerate(ranges[r]):
            conn = mesh.blocks[b].cells[lo:hi]
            used[conn.ravel()] = True
            pieces.append((mesh.blocks[b].cell_type, int(starts[b] + lo), conn))
            if j == 0:
                begin = int(offsets[b] + lo * sizes[b][1])
        nodes = np.flatnonzero(used)
        return begin, split, nodes, mesh.points[nodes], pieces

    return part


def _made(part, body, k: int, source: str) -> dict:
    """This rank's particles of its ``part``: the body's id of the first, positions, volumes."""
    begin, split, nodes, coords, pieces = part
    xs, vols = [np.zeros((0, coords.shape[1]))], [np.zeros(0)]
    label = f"mesh '{body.file}'"
    for cell_type, first, conn in pieces:
        try:
            x, vol, _ = element_particles(coords, cell_type, np.searchsorted(nodes, conn), split,
                                          label, first, conn)
        except SceneError as exc:  # in the scene check's words (parmpm.scene.body_files.keys)
            raise SceneError(f"scene '{source}': bodies.{k}.file: {exc}") from None
        xs.append(x)
        vols.append(vol)
    return {"begin": begin, "x": np.concatenate(xs), "vol": np.concatenate(vols)}
