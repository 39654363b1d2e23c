"""The one place JIT flags are set: every kernel is ``@kernel``-decorated (numba, cached, strict
IEEE arithmetic so results are reproducible bit for bit)."""
from numba import njit

JIT_OPTIONS = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")

kernel = njit(**JIT_OPTIONS)
