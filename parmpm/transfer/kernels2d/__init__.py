"""Hand-specialised 2D transfer kernels: the hot path of the most common runs.

Why a second set of kernels: the dimension-generic ones in :mod:`parmpm.transfer.generic` build every
particle's (node, weight, gradient) list in scratch arrays through one dispatch
(:func:`parmpm.shapes.particle_support`) and loop over a runtime ``d``; that costs ~10× the
arithmetic. These compute the same sums with every loop bound known to the compiler, scattering
each CPDI corner (or the MPM centre) straight into its cell's four nodes and gathering the same
way. They implement exactly the equations documented in :mod:`parmpm.transfer.generic`,
:mod:`parmpm.shapes.cpdi`, :mod:`parmpm.shapes.hat` and :mod:`parmpm.materials`, and the tests
compare them with the generic kernels on random states.

Grid fields come as two node-interleaved blocks per patch slot (so one node's values share a cache
line, and no two fields sit at the same offset modulo 4 KiB):
``gsum[s, node, :] = (m, mv_x, mv_y, f_x, f_y)`` (P2G output) and
``gnew[s, node, :] = (v_x, v_y, Δv_x, Δv_y)`` (grid update output, G2P input).
"""
from parmpm.transfer.kernels2d.bspline import g2p_bspline, p2g_bspline, p2g_momentum_bspline
from parmpm.transfer.kernels2d.cpdi import g2p_cpdi, p2g_cpdi, p2g_momentum_cpdi
from parmpm.transfer.kernels2d.cpdi2 import g2p_cpdi2, p2g_cpdi2, p2g_momentum_cpdi2
from parmpm.transfer.kernels2d.hat import g2p_hat, p2g_hat, p2g_momentum_hat
from parmpm.transfer.kernels2d.mls import g2p_mls, p2g_mls
from parmpm.shapes import BSPLINE, CPDI, CPDI2, MPM

#: interpolator code → (p2g, p2g_momentum, g2p) specialised for 2D
KERNELS_2D = {
    CPDI: (p2g_cpdi, p2g_momentum_cpdi, g2p_cpdi),
    MPM: (p2g_hat, p2g_momentum_hat, g2p_hat),
    BSPLINE: (p2g_bspline, p2g_momentum_bspline, g2p_bspline),  # FLIP and APIC
    CPDI2: (p2g_cpdi2, p2g_momentum_cpdi2, g2p_cpdi2),
}

#: bspline with ``method.transfer = "mls"``: (p2g, p2g_momentum, g2p); its P2G takes the step and
#: an ``account`` flag first (:mod:`parmpm.transfer.kernels2d.mls`)
MLS_KERNELS_2D = (p2g_mls, p2g_momentum_bspline, g2p_mls)

__all__ = ["KERNELS_2D", "MLS_KERNELS_2D"]
