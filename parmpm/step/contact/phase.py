"""The contact phase between velocity fields on this rank: :class:`ContactPhase` (the package's
docstring says what it does); its crack-face part is
:class:`~parmpm.step.contact.crack_sides.CrackSides`."""
from __future__ import annotations

import numpy as np

from decomposition import accumulate, accumulate_max, fill
from parmpm.grid.contact import (GAP_MODES, NORMAL_MODES, contact_correct, contact_extents,
                                 contact_mask, contact_normals, field_of_rows, split_by_field)
from parmpm.grid.update import grid_block
from parmpm.particles.order import slot_subset
from parmpm.core.records import Sides
import parmpm.step.contact.field_grid as field_grid
from parmpm.step.contact.crack_sides import CrackSides
from parmpm.step.contact.field_grid import FieldGrid


class ContactPhase(CrackSides):
    """``field_of_body``: every body's field; ``body_start``: every body's first global id, then
    the total; ``mu``: Coulomb's μ between fields (inf: stick); ``reach``: the interpolator's
    support past a particle's domain, in cells; ``crack``: the damage at which a node's crack
    opens (``[contact] crack_damage``), or None: no crack faces; ``normal``, ``gap``:
    ``[contact] normal`` and ``gap`` (:data:`parmpm.grid.contact.NORMAL_MODES`,
    :data:`~parmpm.grid.contact.GAP_MODES`)."""

    def __init__(self, field_of_body, body_start, mu: float, reach: float, dim: int,
                 crack: float | None = None, normal: str = "separating",
                 gap: str = "column"):
        self.field_of_body = np.asarray(field_of_body, np.int64)
        self.body_start = np.asarray(body_start, np.int64)
        self.fields = int(self.field_of_body.max()) + 1  # body fields
        self.crack = None if crack is None else float(crack)
        self.K = self.fields * (1 if crack is None else 2)
        self.grad = np.zeros((0, 3))  # crack faces: every row's damage gradient
        #: crack faces, this step: the slots near a crack (:meth:`_near_cracks`), or None
        self.near: np.ndarray | None = None
        self.far_boxes = self.near_boxes = None
        self.sides: Sides | None = None
        #: the largest damage of any particle on any rank, from the last step's end (inf: not
        #: known yet); below ``crack`` no node can have a crack
        self.max_damage = np.inf
        self.mu, self.reach, self.dim = float(mu), float(reach), dim
        self.normal_mode, self.gap_mode = NORMAL_MODES[normal], GAP_MODES[gap]
        self.field = np.zeros(0, np.int64)     # every physical row's field
        self.starts = np.zeros((self.K, 1), np.int64)
        self.orders = np.zeros((self.K, 0), np.uint64)
        self.grids: list[FieldGrid] = []
        self.moments: list[FieldGrid] = []   # Σ S m x in rows 1..d (P2G's momentum scatter)
        self.sums: np.ndarray | None = None  # (slots, fields, 6) of the last force update
        #: the first moments taken after the masses' accumulation, from the patches whose boxes
        #: hold a node where fields meet (:meth:`moments_where_fields_meet`); set per step by the
        #: stepper: not with crack faces (one stacked pass) nor mirror faces (whose fold needs
        #: the moments first)
        self.late_moments = False
        #: the slots with a node where fields meet (ghost copies included) and the halo plan
        #: among them, this step (:meth:`moments_where_fields_meet`, :meth:`detect`)
        self.meeting = self.active = None
        #: the slots whose owned nodes two fields reach, this step (:meth:`field_plans`)
        self.meet = None

    def rebuild(self, disc, grid) -> None:
        """Allocate every field's grid like ``grid`` (the stepper's, rebuilt with the patch
        set)."""
        slots, rows, stride = grid.gsum_block.shape
        nodes, d, K = grid.gsum.shape[1], self.dim, self.K
        self.meet = None  # this layout's: made again by field_plans
        spare = max(slots, 2)  # as GridBuffers: never a 0- or 1-slot array; the kernels visit
        # the patches' slots only, and a field's block is its first ``slots`` (C-contiguous)
        if self.crack is None:
            self.sum_all = np.zeros((K, spare, rows, stride))
            self.new_all = np.zeros((K, spare, 2 * d, stride))
            self.x_all = np.zeros((K, spare, 1 + d, stride))
        else:  # stacked: every row holds the fields' copies of the box one after another
            # (field k's node j at j + k·nodes: a stacked index modulo the box's node count is
            # the node), the row padded as the grid's are; seen by the contact kernels as above
            stacked = [grid_block(spare, r, K * nodes)[0] for r in (rows, 2 * d, 1 + d)]
            self.sum_all, self.new_all, self.x_all = (
                b[:, :, :K * nodes].reshape(spare, b.shape[1], K, nodes).transpose(2, 0, 1, 3)
                for b in stacked)
            s, n, x = (b[:slots] for b in stacked)
            self.stacked = FieldGrid(s, n, K * nodes, d, grid.inside)
            self.stacked_x = FieldGrid(x, n, K * nodes, d, grid.inside)
            # what the generic loops write of the slots near a crack (on_sides)
            near = grid_block(spare, rows, K * nodes)[0][:slots]
            self.stacked_near = FieldGrid(near, n, K * nodes, d, grid.inside)
            self.dsum = np.zeros((spare, 2, stride))    # Σ S m, Σ S m D, then D_i
            self.dmax = np.zeros((spare, 1, stride))    # the largest D reaching a node
            self.dsum_spare = np.zeros((spare, 2, stride))  # see _damage_sums
            self.dmax_spare = np.zeros((spare, 1, stride))
            self.reached = np.zeros((spare, 1, stride))  # Σ S m D of the damaged slots
            self.tsum = np.zeros((spare, d + d * (d + 1) // 2, stride))  # Σ S m g, Σ S m g gᵀ
            self.cnormal = np.zeros((spare, 3, stride))  # the crack normal; 0: no crack
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
        if self.fields > 1:  # one body field: every row's is 0, as the array was made
            field_of_rows(R.gid, self.body_start, self.field_of_body, self.field)
        if self.crack is None:
            split_by_field(P.start, P.lazy_order(), self.field, self.starts, self.orders)


    def field_plans(self, plan) -> list:
        """Per field, ``plan`` among the slots holding its particles
        (:meth:`decomposition.HaloPlan.among`): a field's sums are zero in the other slots (its
        P2G zeroes every slot and visits its own particles' only), and only its own particles
        read its velocities' ghost copies, so its exchanges need no other pair; every owned
        node's total, and every copy a particle reads, is the whole plan's, bit for bit. With
        crack faces (one stacked grid that every particle may write): ``[plan]``."""
        if self.crack is not None:
            # one body's far side has mass only at nodes with a crack normal, whose every copy
            # lies in a slot near a crack: its exchanges need those slots' pairs only
            return [plan] if self.near is None else [plan, plan.among(self.near)]
        plans = [plan.among(self.starts[k, 1:] > self.starts[k, :-1]) for k in range(self.K)]
        # fields can meet only at the owned nodes of slots two of them reach
        self.meet = np.sum([p.reached for p in plans], axis=0) >= 2
        return plans

    def field_nodes(self, plans: list, nodes) -> list:
        """Per field, the owned nodes (a :class:`parmpm.core.records.OwnedNodes`) of the slots
        its :meth:`field_plans` plan reaches: elsewhere the field has no mass, and no particle of
        it reads the nodes, so its grid update skips them (their box emptied). With crack faces:
        every owned node, for every field."""
        if len(plans) == 1:
            return [nodes] * self.K
        if self.crack is not None:  # the far side: where a crack can have it
            return [nodes, field_grid.within(nodes, self.near)]
        return [field_grid.within(nodes, p.reached) for p in plans]

    def boxes(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Field ``k``'s (start, order)."""
        return self.starts[k], self.orders[k, :self.starts[k, -1]]

    def node_views(self, which: str, rows: int | None = None) -> list[np.ndarray]:
        """The node-major views of every field's ``which`` ("sum", "new", "x", "normal",
        "ext"), the first ``rows`` rows (default all; "x": the moments' rows 1..d)."""
        blocks = {"sum": self.sum_all, "new": self.new_all, "x": self.x_all,
                  "normal": self.normal, "ext": self.ext}[which]
        slots = self.grids[0].gsum_block.shape[0]
        views = [field_grid.node_major(blocks[k, :slots], self.nodes) for k in range(self.K)]
        if which == "x":
            return [v[:, :, 1:] for v in views]
        return [v if rows is None else v[:, :, :rows] for v in views]

    def active_boxes(self, k: int, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Field ``k``'s (start, order) with only the slots ``active`` marks (the others
        empty)."""
        return slot_subset(*self.boxes(k), active)

    def moments_where_fields_meet(self, transfers, nodes, plan, eps: float,
                                  err: np.ndarray) -> None:
        """Every field's first moments from the particles of the slots whose box holds a node
        where fields meet, accumulated over the ghost layers (collective). A particle of any
        other slot reaches no such node (its slot's copy of the node would be marked), so every
        marked node gets every term, in the order the whole pass adds them; the unmarked nodes'
        moments are partial, and no reader looks at them. A node where fields meet has every copy
        in a marked slot (the mask is filled to the ghost copies), so the moments' ghost sums
        are taken over the marked slots' pairs only (:meth:`decomposition.HaloPlan.among`), as
        are :meth:`detect`'s exchanges after it."""
        slots = self.grids[0].gsum_block.shape[0]
        meet = np.ones(slots, bool) if self.meet is None else self.meet
        self.mask[:slots][~meet] = 0.0
        contact_mask(field_grid.within(nodes, meet), self.sum_all, eps, self.mask)
        mask = field_grid.node_major(self.mask[:slots], self.nodes)
        fill(plan, mask)
        active = mask[:, :, 0].any(axis=1)
        try:
            for k in range(self.K):
                transfers.subset = self.active_boxes(k, active)
                transfers.p2g_momentum(self.moments[k], err, positions=True)
        finally:
            transfers.subset = None
        self.meeting, self.active = plan.among(active), active
        accumulate(self.meeting, *self.node_views("x"))

    def detect(self, disc, P, nodes, plan, eps: float) -> None:
        """Normals at the owned nodes, filled to their ghost copies (and the mask where fields
        meet, unless :meth:`moments_where_fields_meet` marked and filled it this step); the
        fields' extremes along them from every particle near a node, their maxima over the
        ghost layers (collective)."""
        marked = self.late_moments
        slots = self.grids[0].gsum_block.shape[0]
        visit, filled = nodes, plan
        if marked:
            visit, filled = field_grid.within(nodes, self.active), self.meeting
        elif self.crack is not None and self.near is not None:
            # one body's crack faces meet only at nodes with a crack normal, each copy of which
            # lies in a slot near a crack
            self.mask[:slots][~self.near] = 0.0
            visit, filled = field_grid.within(nodes, self.near), plan.among(self.near)
        contact_normals(disc.dim, visit, disc.origin3, disc.h3, self.sum_all, self.x_all, eps,
                        self.normal_mode, self.normal, self.mask, marked)
        mask = field_grid.node_major(self.mask[:slots], self.nodes)
        # the normals are read where fields meet only: every copy of such a node is in a slot
        # the (filled) mask marks, so the marked slots' pairs carry them all
        fill(filled, *self.node_views("normal"), *(() if marked else (mask,)))
        active = mask[:, :, 0].any(axis=1)  # slots with a node where fields meet
        meeting = self.meeting if marked else plan.among(active)
        self.active = active
        # only there are extremes read (a slot without such a node holds no copy of one)
        self.ext[:, :slots][:, active] = -np.inf
        R = P.rows
        contact_extents(disc.dim, P.start, P.order(), self.field, R.x, R.F, R.r0, disc.origin3,
                        disc.h3, self.reach, disc.base, disc.nloc, self.normal, self.mask,
                        active, self.ext, self.sides if self.crack is not None else None,
                        self.gap_mode)
        accumulate_max(meeting, *self.node_views("ext"))

    def untouched(self, slots: int) -> None:
        """A step without the contact phase (a crack scene with no crack yet): no impulse and no
        work on any field, as :meth:`correct` would sum them."""
        if self.sums is None or self.sums.shape != (slots, self.K, 6):
            self.sums = np.zeros((slots, self.K, 6))
        else:
            self.sums[:] = 0.0

    def correct(self, disc, nodes, dt: float, gravity: np.ndarray, heavy: float, eps: float,
                momentum_only: bool) -> None:
        """The contact correction of every field's updated velocities at the owned nodes where
        fields meet (those of the slots :meth:`detect` marked this step)."""
        g = np.zeros(3)
        g[:disc.dim] = gravity[:disc.dim]
        sums = contact_correct(disc.dim, field_grid.within(nodes, self.active), self.sum_all, self.new_all,
                               self.normal, self.ext, self.mu, dt, g, heavy, eps, momentum_only,
                               self.normal_mode, self.mask)
        if not momentum_only:
            self.sums = sums
