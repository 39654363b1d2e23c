"""Which transfer kernels a stepper calls, and the one call of each kind.

Three kinds — P2G, P2G's momentum re-map (MUSL), G2P — each with one signature here, whatever
runs behind it: the hand-specialised 2D/3D kernels (:mod:`parmpm.transfer.kernels2d`,
:mod:`parmpm.transfer.kernels3d`) where the dimension and interpolator have them, MLS's own
(its P2G takes the step), or the dimension-generic loops of :mod:`parmpm.transfer.generic`
(the reference the specialised ones are tested against).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from parmpm.core.records import AXES, Boxes, Fields, Locate, Material, Method
from parmpm.shapes import CPDI, KINDS
from parmpm.transfer.affine import AFFINE_TRANSFERS, inertia_diagonal
from parmpm.transfer.generic import g2p, p2g, p2g_momentum, support_nodes
from parmpm.transfer.kernels2d import KERNELS_2D, MLS_KERNELS_2D
from parmpm.transfer.kernels2d.support_nodes import support_nodes_cpdi as support_nodes_cpdi_2d
from parmpm.transfer.kernels3d import KERNELS_3D, MLS_KERNELS_3D
from parmpm.transfer.kernels3d.support_nodes import support_nodes_cpdi as support_nodes_cpdi_3d

#: one interpolator's specialised kernels, by name
Kernels = namedtuple("Kernels", ("p2g", "p2g_momentum", "g2p"))

#: dimension → {interpolator code → Kernels} of the hand-specialised kernels
SPECIALISED = {dim: {code: Kernels(*triple) for code, triple in table.items()}
               for dim, table in ((2, KERNELS_2D), (3, KERNELS_3D))}
#: dimension → the MLS transfers' Kernels (bspline; its P2G takes the step)
SPECIALISED_MLS = {2: Kernels(*MLS_KERNELS_2D), 3: Kernels(*MLS_KERNELS_3D)}
#: dimension → the specialised CPDI walk of the separation count's nodes
SUPPORT_NODES = {2: support_nodes_cpdi_2d, 3: support_nodes_cpdi_3d}


class Transfers:
    """The transfers of one rank: ``apic`` (affine velocity fields, APIC or MLS), ``mls``
    (the moving-least-squares gradient, ``Δt f`` folded into P2G's momentum), ``inertia``
    (``diag D_p`` of the affine transfers, zeros under FLIP), ``kernels`` (the specialised
    :data:`Kernels` in use, or None for the generic loops)."""

    def __init__(self, disc, particles, params: np.ndarray, flip: float, transfer: str):
        self.disc, self.P, self.params, self.flip = disc, particles, params, flip
        self.apic = transfer in AFFINE_TRANSFERS
        self.mls = transfer == "mls"
        self.inertia = inertia_diagonal(disc.method, disc.h, self.apic)
        self.kernels: Kernels | None = None
        self.empty_boxes = False  # no slot, an index order: see Stepper.compile_lazy_order
        #: (start, order) of the particles to visit instead of all (a contact field's), or None
        self.subset: tuple[np.ndarray, np.ndarray] | None = None
        #: crack faces (:data:`parmpm.core.records.Sides`: every particle to its field at each
        #: node of a stacked grid; the generic loops, and the specialised ones where
        #: :meth:`chooses_sides`), or None
        self.sides = None
        #: whether G2P measures the CFL speed (False with a fixed step: the specialised kernels
        #: are compiled without it, :mod:`parmpm.transfer.running_speed`)
        self.cfl = True
        self._zero_affine: np.ndarray | None = None  # see _no_affine
        self.use("specialised")

    def use(self, kind: str) -> None:
        """``"specialised"``: the hand-specialised kernels where this dimension and method have
        them (the default); ``"generic"``: the dimension-generic ones."""
        if kind == "specialised":
            # APIC and MLS runs are bspline runs (the scene and inertia_diagonal refuse
            # others), whose kernels see the affine field; MLS has kernels of its own
            if self.mls:
                self.kernels = SPECIALISED_MLS.get(self.disc.dim)
            else:
                self.kernels = SPECIALISED.get(self.disc.dim, {}).get(self.disc.method)
        elif kind == "generic":
            self.kernels = None
        else:
            raise ValueError(f'kernels: expected "specialised" or "generic", got {kind!r}')

    def chooses_sides(self) -> bool:
        """Whether the kernels in use choose each node's copy of a crack face themselves (the
        specialised 2D ones, :mod:`parmpm.transfer.sided`), so that crack faces need not send
        the particles near a crack to the generic loops."""
        return self.kernels is not None and self.disc.dim == 2

    def records(self):
        """The kernels' records (:mod:`parmpm.core.records`) of the current patches and
        particle arrays (rebuilt per call: migration replaces the arrays)."""
        D, P = self.disc, self.P
        R = P.rows  # physical rows, visited in P.order(): no copy of the fields per step
        # the specialised loops are compiled twice, for rows in canonical order (None: no index
        # load) and for a lazy order; the generic ones, slower anyway, once (an index always):
        # every compile of a generic loop is seconds, and a fresh clone's tests pay each
        order = P.lazy_order() if self.kernels is not None else P.order()
        start = P.start
        if self.subset is not None:
            start, order = self.subset
        boxes = Boxes(start, order, D.base, D.jlo, D.jhi, D.nloc, D.nglob, D.origin3,
                      D.inv_h3)
        if self.empty_boxes:
            boxes = boxes._replace(start=np.zeros(1, np.int64), order=np.zeros(0, np.uint64))
        fields = Fields(R.x, R.v, R.F, R.r0, R.lh0, R.mass, R.vol0, R.stress, R.dx, R.affine,
                        R.corners, R.rf, self.sides if self.kernels is not None else None)
        return (Method(D.method, AXES[D.dim], D.lcr, self.apic, self.mls, KINDS[D.method]), boxes,
                fields)

    def p2g(self, grid, bforce: np.ndarray, dt: float, err: np.ndarray, account: bool) -> None:
        """Mass, momentum and force of every slot into ``grid``'s sums (MLS folds ``Δt f`` into
        the momentum; its kernel writes the force rows only when ``account``: the ledger)."""
        how, boxes, fields = self.records()
        k = self.kernels
        if k is not None and self.mls:
            k.p2g(dt, account, boxes, boxes.order, fields, bforce, grid.gsum_block, err)
        elif k is not None:
            k.p2g(how.lcr, boxes, boxes.order, fields, bforce, grid.gsum_block, err)
        else:
            p2g(how, boxes, fields, bforce, dt, (grid.gm, grid.gmv, grid.gf), err, self.sides)

    def p2g_momentum(self, grid, err: np.ndarray, positions: bool = False) -> None:
        """MUSL's re-map: the momentum of the updated particle velocities alone; ``positions``:
        the first moment ``Σ S m x`` instead (contact's normals: positions for velocities, no
        affine part)."""
        how, boxes, fields = self.records()
        if positions:
            fields = fields._replace(v=fields.x, affine=self._no_affine(fields.affine))
        if self.kernels is not None:
            self.kernels.p2g_momentum(how.lcr, boxes, boxes.order, fields, grid.gsum_block, err)
        else:
            p2g_momentum(how, boxes, fields, grid.gmv, err, self.sides)

    def support_nodes(self, nodes: np.ndarray, count: np.ndarray, err: np.ndarray) -> None:
        """Every particle's nodes of nonzero weight, each once (the separation count's input:
        :func:`parmpm.transfer.generic.support_nodes`, whose arrays the 2D and 3D CPDI walks of
        the step's own corners reproduce where the specialised kernels run)."""
        how, boxes, fields = self.records()
        walk = SUPPORT_NODES.get(self.disc.dim) if self.disc.method == CPDI else None
        if self.kernels is not None and walk is not None:
            walk(how.lcr, boxes, boxes.order, fields, nodes, count, err)
        else:
            support_nodes(how, boxes, fields, nodes, count, err)

    def _no_affine(self, affine: np.ndarray) -> np.ndarray:
        """Zero affine matrices shaped like ``affine`` (kept: a fresh one each step would be
        garbage)."""
        if self._zero_affine is None or self._zero_affine.shape != affine.shape:
            self._zero_affine = np.zeros_like(affine)
        return self._zero_affine

    def g2p(self, grid, mode: int, dt: float, err: np.ndarray, locate: Locate | None):
        """G2P in ``mode`` (:mod:`parmpm.transfer.update_order`); returns (the largest wave
        speed, (first particle off the grid, particles that changed patch) or None). The
        specialised kernels find each particle's next patch once its position is final
        (``locate``), one pass over the particles fewer than the migration's own search."""
        how, boxes, fields = self.records()
        P = self.P
        # the generic loops always measure the speed: one compilation of them, not two
        cfl = True if self.cfl or self.kernels is None else None
        material = Material(P.rows.mat, self.params, P.rows.damage, cfl)
        if self.kernels is not None:
            vmax, moved, first_out = self.kernels.g2p(mode, how.lcr, boxes, boxes.order, dt,
                                                      self.flip, fields, material,
                                                      grid.gnew_block, err, locate)
            return vmax, (first_out, moved)
        return g2p(mode, how, boxes, dt, self.flip, fields, material, (grid.gvel, grid.gdv),
                   err, self.sides), None
