"""Particle <-> grid transfers: generic loops, specialised 2D/3D kernels, update orders, affine transfers."""
