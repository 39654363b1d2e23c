"""Hand-specialised 3D transfer kernels (none yet: every 3D run uses :mod:`parmpm.transfer`)."""

#: interpolator code → (p2g, p2g_momentum, g2p) specialised for 3D
KERNELS_3D: dict = {}

__all__ = ["KERNELS_3D"]
