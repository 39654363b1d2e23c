"""Hand-specialised 3D transfer kernels: the 3D counterpart of :mod:`parmpm.transfer.kernels2d`.

The dimension-generic kernels in :mod:`parmpm.transfer.generic` build every particle's (node, weight,
gradient) list in scratch arrays (64 entries for a 3D CPDI particle) and loop over a runtime
``d``. These compute the same sums with every loop bound known to the compiler, scattering each
CPDI corner (or the MPM centre) straight into its cell's eight nodes and gathering the same way,
with per-particle state held in scalars. They implement exactly the equations documented in
:mod:`parmpm.transfer.generic`, :mod:`parmpm.shapes.cpdi`, :mod:`parmpm.shapes.scaling`,
:mod:`parmpm.shapes.hat` and :mod:`parmpm.materials`, and the tests compare them with the generic
kernels on random states.

Grid fields come as two row blocks per patch slot (:func:`parmpm.grid.update.grid_block`):
``gsum[s, :, node] = (m, mv_x, mv_y, mv_z, f_x, f_y, f_z)`` (P2G output) and
``gnew[s, :, node] = (v_x, v_y, v_z, Δv_x, Δv_y, Δv_z)`` (grid update output, G2P input), with
``node = i0 + L0 (i1 + L1 i2)`` in the patch's ghost-inclusive box.
"""
from parmpm.transfer.kernels3d.bspline import g2p_bspline, p2g_bspline, p2g_momentum_bspline
from parmpm.transfer.kernels3d.cpdi import g2p_cpdi, p2g_cpdi, p2g_momentum_cpdi
from parmpm.transfer.kernels3d.cpdi2 import g2p_cpdi2, p2g_cpdi2, p2g_momentum_cpdi2
from parmpm.transfer.kernels3d.hat import g2p_hat, p2g_hat, p2g_momentum_hat
from parmpm.transfer.kernels3d.mls import g2p_mls, p2g_mls
from parmpm.shapes import BSPLINE, CPDI, CPDI2, MPM

#: interpolator code → (p2g, p2g_momentum, g2p) specialised for 3D
KERNELS_3D = {
    CPDI: (p2g_cpdi, p2g_momentum_cpdi, g2p_cpdi),
    MPM: (p2g_hat, p2g_momentum_hat, g2p_hat),
    BSPLINE: (p2g_bspline, p2g_momentum_bspline, g2p_bspline),  # FLIP and APIC
    CPDI2: (p2g_cpdi2, p2g_momentum_cpdi2, g2p_cpdi2),
}

#: bspline with ``method.transfer = "mls"``: (p2g, p2g_momentum, g2p); its P2G takes the step and
#: an ``account`` flag first (:mod:`parmpm.transfer.kernels3d.mls`)
MLS_KERNELS_3D = (p2g_mls, p2g_momentum_bspline, g2p_mls)

__all__ = ["KERNELS_3D", "MLS_KERNELS_3D"]
