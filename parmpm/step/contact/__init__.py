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

The package: :mod:`.field_grid` (the per-field grids), :mod:`.phase` (:class:`ContactPhase`),
:mod:`.crack_sides` (its crack-face part).
"""
from parmpm.step.contact.field_grid import FieldGrid
from parmpm.step.contact.phase import ContactPhase

__all__ = ["ContactPhase", "FieldGrid"]
