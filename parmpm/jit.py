"""The one place JIT flags are set: every kernel is ``@kernel``-decorated (numba, cached, strict
IEEE arithmetic so results are reproducible bit for bit). ``@inline_kernel`` marks the small
per-particle helpers of hot loops: numba inlines them into the caller's IR, so the compiler sees
one loop body (a call per corner through LLVM costs ~2× in P2G)."""
from numba import njit

JIT_OPTIONS = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")

kernel = njit(**JIT_OPTIONS)
inline_kernel = njit(inline="always", **JIT_OPTIONS)
