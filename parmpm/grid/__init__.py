"""The grid: nodal update, boundary and symmetry conditions, patch-box arithmetic for kernels."""
