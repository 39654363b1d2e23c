"""Crack faces in the contact phase (``[contact] cracks``, :mod:`parmpm.grid.crack`): the damage
field, every particle's damage gradient and every node's crack normal (:meth:`CrackSides.find_sides`),
which slots lie near a crack, whether a step can run as one field (:meth:`CrackSides.whole`), and
the transfers over the stacked grid of both sides (:meth:`CrackSides.on_sides`).

:class:`CrackSides` is the part of :class:`parmpm.step.contact.ContactPhase` that only a crack
scene uses; it reads the phase's grids and fields (``grids``, ``nodes``, ``field``, ``fields``,
``crack``, the damage blocks made by ``rebuild``) and sets ``grad``, ``cnormal``, ``near``,
``sides`` and ``max_damage``.
"""
from __future__ import annotations

import math

import numpy as np

from decomposition import accumulate, allreduce_max, fill
from parmpm.core.records import Sides
from parmpm.grid.crack import crack_normals, nodal_damage, slots_with_crack
from parmpm.particles.order import slot_subset, slots_holding_positive
import parmpm.step.contact.field_grid as field_grid
from parmpm.transfer.damage_field import damage_gradients, damage_sums


class CrackSides:
    """The crack-face methods of :class:`parmpm.step.contact.ContactPhase` (a mixin: it holds no
    state of its own)."""

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
        dsum, dmax = field_grid.node_major(self.dsum[:slots], self.nodes), field_grid.node_major(self.dmax[:slots], self.nodes)
        damage = P.rows.damage
        wet = self._damage_sums(transfers, P, plan, damage, slots, err)
        # every sum below is zero in the other slots, and every copy of a node a damaged
        # particle reaches lies in a wet slot: their exchanges and node passes need no other
        wet_plan, wet_nodes = plan.among(wet), field_grid.within(nodes, wet)
        accumulate(wet_plan, dsum, maxima=(dmax,))
        nodal_damage(wet_nodes, self.dsum)
        fill(wet_plan, dsum[:, :, 1:])
        tsum = field_grid.node_major(self.tsum[:slots], self.nodes)
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
        fill(wet_plan, field_grid.node_major(self.cnormal[:slots], self.nodes))
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
        dsum, dmax = field_grid.node_major(self.dsum[:slots], self.nodes), field_grid.node_major(self.dmax[:slots], self.nodes)
        try:
            transfers.subset = slot_subset(P.start, order, damaged)
            how, boxes, fields = transfers.records()
            damage_sums(how, boxes, fields, damage, dsum, dmax, err)
            reach = field_grid.node_major(self.reached[:slots], self.nodes)
            np.copyto(reach[:, :, 0], dsum[:, :, 1])
            accumulate(plan, reach)
            fill(plan, reach)
            wet = np.any(reach[:, :, 0] > 0.0, axis=1)
            others = wet & ~damaged
            if others.any():
                transfers.subset = slot_subset(P.start, order, others)
                how, boxes, fields = transfers.records()
                spare, spare_max = (field_grid.node_major(b[:slots], self.nodes)
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
