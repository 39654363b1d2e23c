"""The step's contact between velocity fields on this rank (``[contact]``): every field's own grid,
the particles of each field, and the contact phase between the grid update and G2P
(:mod:`parmpm.grid.contact`).

Each field's grid is a :class:`FieldGrid` (what the transfers and the grid update read of
:class:`~parmpm.step.grid_buffers.GridBuffers`), a slice of one array over all fields so that the
contact kernels see every field at a node. A particle's field is its body's
(``contact.fields``), found from its global id each step (bodies are numbered in seeding order),
so nothing is stored, moved or checkpointed for it. The transfers run once per field on that
field's share of the canonical particle order (:func:`parmpm.grid.contact.split_by_field`): each
field's sums are added in the same order as a single field's, on any number of ranks.
"""
from __future__ import annotations

import numpy as np

from decomposition import accumulate_max, fill
from parmpm.grid.contact import (contact_correct, contact_extents, contact_normals,
                                 field_of_rows, split_by_field)


def _views(block: np.ndarray, nodes: int) -> np.ndarray:
    """The node-major view ``(slots, nodes, rows)`` of a ``(slots, rows, stride)`` block."""
    return block[:, :, :nodes].transpose(0, 2, 1)


class FieldGrid:
    """One field's grid fields, as :class:`~parmpm.step.grid_buffers.GridBuffers` names them."""

    def __init__(self, gsum_block, gnew_block, nodes: int, d: int, inside: np.ndarray):
        self.gsum_block, self.gnew_block = gsum_block, gnew_block
        self.gsum, self.gnew = _views(gsum_block, nodes), _views(gnew_block, nodes)
        self.gm, self.gmv, self.gf = (self.gsum[:, :, :1], self.gsum[:, :, 1:1 + d],
                                      self.gsum[:, :, 1 + d:])
        self.gvel, self.gdv = self.gnew[:, :, :d], self.gnew[:, :, d:]
        self.inside = inside


class ContactPhase:
    """``field_of_body``: every body's field; ``body_start``: every body's first global id, then
    the total; ``mu``: Coulomb's μ between fields (inf: stick); ``reach``: the interpolator's
    support past a particle's domain, in cells."""

    def __init__(self, field_of_body, body_start, mu: float, reach: float, dim: int):
        self.field_of_body = np.asarray(field_of_body, np.int64)
        self.body_start = np.asarray(body_start, np.int64)
        self.K = int(self.field_of_body.max()) + 1
        self.mu, self.reach, self.dim = float(mu), float(reach), dim
        self.field = np.zeros(0, np.int64)     # every physical row's field
        self.starts = np.zeros((self.K, 1), np.int64)
        self.orders = np.zeros((self.K, 0), np.uint64)
        self.grids: list[FieldGrid] = []
        self.moments: list[FieldGrid] = []   # Σ S m x in rows 1..d (P2G's momentum scatter)
        self.sums: np.ndarray | None = None  # (slots, fields, 6) of the last force update

    def rebuild(self, disc, grid) -> None:
        """Allocate every field's grid like ``grid`` (the stepper's, rebuilt with the patch
        set)."""
        slots, rows, stride = grid.gsum_block.shape
        nodes, d, K = grid.gsum.shape[1], self.dim, self.K
        spare = max(slots, 2)  # as GridBuffers: never a 0- or 1-slot array; the kernels visit
        # the patches' slots only, and a field's block is its first ``slots`` (C-contiguous)
        self.sum_all = np.zeros((K, spare, rows, stride))
        self.new_all = np.zeros((K, spare, 2 * d, stride))
        self.x_all = np.zeros((K, spare, 1 + d, stride))
        self.normal = np.zeros((K, spare, 2 * d, stride))  # two candidates
        self.ext = np.zeros((K, spare, 4, stride))  # two extremes per candidate
        self.mask = np.zeros((spare, 1, stride))     # 1 at a node where fields meet
        self.grids = [FieldGrid(self.sum_all[k, :slots], self.new_all[k, :slots], nodes, d,
                                grid.inside) for k in range(K)]
        self.moments = [FieldGrid(self.x_all[k, :slots], self.new_all[k, :slots], nodes, d,
                                  grid.inside) for k in range(K)]
        self.nodes = nodes

    def split(self, P) -> None:
        """Every row's field and every field's share of the canonical order (after
        migration)."""
        n = P.n
        if self.field.size != n:
            self.field = np.zeros(n, np.int64)
            self.orders = np.zeros((self.K, n), np.uint64)
        if self.starts.shape[1] != P.start.size:
            self.starts = np.zeros((self.K, P.start.size), np.int64)
        R = P.rows
        field_of_rows(R.gid, self.body_start, self.field_of_body, self.field)
        split_by_field(P.start, P.lazy_order(), self.field, self.starts, self.orders)

    def boxes(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Field ``k``'s (start, order)."""
        return self.starts[k], self.orders[k, :self.starts[k, -1]]

    def node_views(self, which: str, rows: int | None = None) -> list[np.ndarray]:
        """The node-major views of every field's ``which`` ("sum", "new", "x", "normal",
        "ext"), the first ``rows`` rows (default all; "x": the moments' rows 1..d)."""
        blocks = {"sum": self.sum_all, "new": self.new_all, "x": self.x_all,
                  "normal": self.normal, "ext": self.ext}[which]
        slots = self.grids[0].gsum_block.shape[0]
        views = [_views(blocks[k, :slots], self.nodes) for k in range(self.K)]
        if which == "x":
            return [v[:, :, 1:] for v in views]
        return [v if rows is None else v[:, :, :rows] for v in views]

    def detect(self, disc, P, nodes, plan, eps: float) -> None:
        """Normals at the owned nodes, filled to their ghost copies; the fields' extremes along
        them from every particle near a node, their maxima over the ghost layers (collective)."""
        contact_normals(disc.dim, nodes, disc.origin3, disc.h3, self.sum_all, self.x_all, eps,
                        self.normal, self.mask)
        slots = self.grids[0].gsum_block.shape[0]
        mask = _views(self.mask[:slots], self.nodes)
        fill(plan, *self.node_views("normal"), mask)
        active = mask[:, :, 0].any(axis=1)  # slots with a node where fields meet
        # only there are extremes read (a slot without such a node holds no copy of one)
        self.ext[:, :slots][:, active] = -np.inf
        R = P.rows
        contact_extents(disc.dim, P.start, P.order(), self.field, R.x, R.F, R.r0, disc.origin3,
                        disc.h3, self.reach, disc.base, disc.nloc, self.normal, self.mask,
                        active, self.ext)
        accumulate_max(plan, *self.node_views("ext"))

    def correct(self, disc, nodes, dt: float, gravity: np.ndarray, heavy: float, eps: float,
                momentum_only: bool) -> None:
        """The contact correction of every field's updated velocities at the owned nodes."""
        g = np.zeros(3)
        g[:disc.dim] = gravity[:disc.dim]
        sums = contact_correct(disc.dim, nodes, self.sum_all, self.new_all, self.normal,
                               self.ext, self.mu, dt, g, heavy, eps, momentum_only)
        if not momentum_only:
            self.sums = sums
