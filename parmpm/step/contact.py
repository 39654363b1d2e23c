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

With crack faces (``[contact] cracks``, :mod:`parmpm.grid.crack`) every body field has a second
field, the far side of a crack, and a particle's field is chosen per node inside the transfer
loops: the grids of all fields are then one stacked grid (field ``k``'s node ``j`` at
``j + k · stride``, the arrays laid out (slots, rows, fields, stride)) that one pass of the
generic transfers fills, and each field's grid a view into it. Until a particle can crack, a
scene of one body steps without them (:meth:`ContactPhase.whole`).
"""
from __future__ import annotations

import math

import numpy as np

from decomposition import accumulate, accumulate_max, allreduce_max, fill
from parmpm.core.records import Sides
from parmpm.grid.contact import (GAP_MODES, NORMAL_MODES, contact_correct, contact_extents,
                                 contact_mask, contact_normals, field_of_rows, split_by_field)
from parmpm.grid.crack import crack_normals, nodal_damage, slots_with_crack
from parmpm.grid.update import grid_block
from parmpm.particles.order import slot_subset, slots_holding_positive
from parmpm.transfer.damage_field import damage_gradients, damage_sums


def _within(nodes, slots: np.ndarray):
    """``nodes`` (:class:`parmpm.core.records.OwnedNodes`) with the boxes of the slots
    ``slots`` does not mark emptied: a pass over the nodes where fields meet visits those
    slots' only."""
    return nodes._replace(own_hi=np.where(slots[:, None], nodes.own_hi, nodes.own_lo))


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

    def find_sides(self, transfers, P, plan, nodes, err: np.ndarray) -> None:
        """Crack faces: the damage field, every particle's damage gradient and every node's
        crack normal (collective: six halo exchanges), as :attr:`sides` for this step's transfers
        (:mod:`parmpm.grid.crack`). While no particle anywhere is damaged enough for a crack
        (:attr:`max_damage`, the same on every rank) every node's normal is zero without a
        pass: what the passes would find."""
        slots = self.grids[0].gsum_block.shape[0]
        if self.grad.shape[0] != P.n:
            self.grad = np.zeros((P.n, 3))
        if self.max_damage < self.crack:
            self.cnormal[:slots] = 0.0
            self._near_cracks(P)
            return
        dsum, dmax = _views(self.dsum[:slots], self.nodes), _views(self.dmax[:slots], self.nodes)
        damage = P.rows.damage
        wet = self._damage_sums(transfers, P, plan, damage, slots, err)
        # every sum below is zero in the other slots, and every copy of a node a damaged
        # particle reaches lies in a wet slot: their exchanges and node passes need no other
        wet_plan, wet_nodes = plan.among(wet), _within(nodes, wet)
        accumulate(wet_plan, dsum, maxima=(dmax,))
        nodal_damage(wet_nodes, self.dsum)
        fill(wet_plan, dsum[:, :, 1:])
        tsum = _views(self.tsum[:slots], self.nodes)
        try:  # a particle of any other slot has no damage gradient
            self.grad[:] = 0.0
            transfers.subset = slot_subset(P.start, P.order(), wet)
            how, boxes, fields = transfers.records()
            damage_gradients(how, boxes, fields, dsum[:, :, 1:], self.grad, tsum, err)
        finally:
            transfers.subset = None
        accumulate(wet_plan, tsum)
        self.cnormal[:slots][~wet] = 0.0  # a crack's node has every copy in a wet slot
        crack_normals(self.dim, wet_nodes, self.tsum, self.dmax, self.crack, self.cnormal)
        fill(wet_plan, _views(self.cnormal[:slots], self.nodes))
        self._near_cracks(P, wet)

    def _damage_sums(self, transfers, P, plan, damage, slots: int, err) -> np.ndarray:
        """Every slot's partial damage sums (:func:`damage_sums`) where they can matter; returns
        the slots whose node box (ghost copies included) a damaged particle reaches. Elsewhere
        every node's damage is 0 whatever its mass, so the slots whose box no damaged particle
        reaches are left out (their sums zero): first the slots holding a damaged particle, then
        — once their ``Σ S m D``, summed and filled over the ghost layers (collective: on every
        rank, whatever it holds), shows which boxes they reach — the other slots of those boxes,
        each slot's sums its own particles' in canonical order as in one pass over all, so every
        node's damage is that pass's, bit for bit."""
        order = P.order()
        damaged = slots_holding_positive(P.start, order, damage)
        dsum, dmax = _views(self.dsum[:slots], self.nodes), _views(self.dmax[:slots], self.nodes)
        try:
            transfers.subset = slot_subset(P.start, order, damaged)
            how, boxes, fields = transfers.records()
            damage_sums(how, boxes, fields, damage, dsum, dmax, err)
            reach = _views(self.reached[:slots], self.nodes)
            np.copyto(reach[:, :, 0], dsum[:, :, 1])
            accumulate(plan, reach)
            fill(plan, reach)
            wet = np.any(reach[:, :, 0] > 0.0, axis=1)
            others = wet & ~damaged
            if others.any():
                transfers.subset = slot_subset(P.start, order, others)
                how, boxes, fields = transfers.records()
                spare, spare_max = (_views(b[:slots], self.nodes)
                                    for b in (self.dsum_spare, self.dmax_spare))
                damage_sums(how, boxes, fields, damage, spare, spare_max, err)
                self.dsum[:slots][others] = self.dsum_spare[:slots][others]
            return wet
        finally:
            transfers.subset = None

    def _near_cracks(self, P, wet: np.ndarray | None = None) -> None:
        """This step's :attr:`near` (per slot: its node box, ghost copies included, holds a node
        with a crack normal; None where a particle's field away from a crack is not field 0:
        several bodies) and the (start, order) of the slots it marks and of the others."""
        self.near = self.far_boxes = self.near_boxes = None
        slots = self.grids[0].gsum_block.shape[0]
        # two fields' copies of a node are a box's node count apart in the stacked grid
        self.sides = Sides(self.field, self.fields, self.grad, self.cnormal, self.nodes,
                           np.ones(slots, bool))
        if self.fields != 1:
            return
        self.near = np.zeros(slots, bool)  # wet None: no crack normal anywhere
        if wet is not None:  # a node with a crack normal has every copy in a wet slot
            self.near[wet] = slots_with_crack(self.cnormal[:slots][wet], int(wet.sum()),
                                              self.nodes)
        self.sides = self.sides._replace(near=self.near)
        self.far_boxes = slot_subset(P.start, P.order(), ~self.near)
        self.near_boxes = slot_subset(P.start, P.order(), self.near)

    def whole(self, damage: np.ndarray, comm) -> bool:
        """A crack scene of one body with no particle anywhere damaged to ``crack`` (the last
        step's largest damage, the same on every rank; at a run's first step, a restart's
        included, the particles' own ``damage``: collective): every particle is then in its
        body's field at every node and the far side is empty, so the step is one field's."""
        if self.crack is None or self.fields != 1:
            return False
        if not math.isfinite(self.max_damage):
            local = np.array([float(damage.max(initial=0.0))])
            self.max_damage = float(allreduce_max(comm, local)[0])
        return self.max_damage < self.crack

    def on_sides(self, transfers, kernels: str, transfer, grid, spare=None, rows=None,
                 far: bool = True) -> list:
        """``transfer(grid)`` over the stacked grid of crack faces. In a scene of one body on
        kernels that choose each node's copy themselves (the specialised 2D ones:
        :meth:`parmpm.step.transfers.Transfers.chooses_sides`), one pass over every slot (with
        ``far`` False, the slots near a crack). Otherwise the slots whose node box
        (ghost copies included) holds no node with a crack normal on the ``kernels`` asked for
        (the specialised ones by default) — in a scene of one body their particles are in its
        field, field 0's copies, at every node — and the others on the generic loops with each
        particle's field per node; those write into ``spare`` (a grid like ``grid``: every pass
        zeroes its sums first), whose ``rows`` of those slots are then copied into ``grid``
        (``spare`` None: the transfer writes no grid). Each slot's sums are its own particles'
        in canonical order, whichever kernels, so the same on any number of ranks. ``far``
        False: the slots near a crack only (the others' sums zero): where fields meet is at a
        node with a crack normal, which every slot whose box holds it counts as near, so sums
        read only there (the first moments) need no other slot. Returns what each pass
        returned."""
        T, near = transfers, self.near
        out = []
        T.use(kernels)
        if near is not None and T.chooses_sides():  # one pass: each node's copy in the loops
            try:
                T.sides = self.sides
                if not far:
                    T.subset = self.near_boxes
                return [transfer(grid)]
            finally:
                T.subset = None
                T.sides = None
                T.use("generic")
        try:
            target = grid
            if near is not None and not near.all():
                if far:
                    T.use(kernels)
                    T.subset = self.far_boxes
                    out.append(transfer(grid))
                    if not near.any():
                        return out
                    target = grid if spare is None else spare
                T.subset = self.near_boxes
            T.use("generic")
            T.sides = self.sides
            out.append(transfer(target))
            if target is not grid:
                grid.gsum_block[near, rows] = target.gsum_block[near, rows]
        finally:
            T.subset = None
            T.sides = None
            T.use("generic")
        return out

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
            return [nodes, _within(nodes, self.near)]
        return [_within(nodes, p.reached) for p in plans]

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
        contact_mask(_within(nodes, meet), self.sum_all, eps, self.mask)
        mask = _views(self.mask[:slots], self.nodes)
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
            visit, filled = _within(nodes, self.active), self.meeting
        elif self.crack is not None and self.near is not None:
            # one body's crack faces meet only at nodes with a crack normal, each copy of which
            # lies in a slot near a crack
            self.mask[:slots][~self.near] = 0.0
            visit, filled = _within(nodes, self.near), plan.among(self.near)
        contact_normals(disc.dim, visit, disc.origin3, disc.h3, self.sum_all, self.x_all, eps,
                        self.normal_mode, self.normal, self.mask, marked)
        mask = _views(self.mask[:slots], self.nodes)
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
        sums = contact_correct(disc.dim, _within(nodes, self.active), self.sum_all, self.new_all,
                               self.normal, self.ext, self.mu, dt, g, heavy, eps, momentum_only,
                               self.normal_mode, self.mask)
        if not momentum_only:
            self.sums = sums
