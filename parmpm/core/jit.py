"""The one place JIT flags are set: every kernel is ``@kernel``-decorated (numba, cached, strict
IEEE arithmetic so results are reproducible bit for bit). ``@inline_kernel`` marks the small
per-particle helpers of hot loops: numba inlines them into the caller's IR, so the compiler sees
one loop body (a call per corner through LLVM costs ~2× in P2G).

The dimension-generic transfers (:mod:`parmpm.transfer.generic`, :mod:`parmpm.shapes`,
:mod:`parmpm.materials`) hand scratch arrays and per-particle views (``F[i]``) to helpers with
branches and loops. With numba's reference counting on, every such array costs an atomic
incref/decref pair per call that LLVM cannot prune — 55–70 % of a generic 1D P2G's time — and
numba-IR inlining keeps the pairs while making cold compiles ~6× slower. So those kernels come in
two more flavours with reference counting off (``_nrt=False``). They may index, slice and write
the arrays they are given but never allocate or return one (allocating fails to compile, so the
contract is checked):

* ``@loop_kernel``: a particle loop; its scratch comes from a ``@kernel`` wrapper;
* ``@helper_kernel``: a per-particle helper, inlined by LLVM (``forceinline``) into its caller:
  compiled once, no call cost.

Every one of them is cached on disk keyed to the whole source of the package
(:mod:`parmpm.core.cache_key`): numba's own key is the kernel's file alone, and a kernel's machine code
holds the helpers it calls from other modules.
"""
from numba import njit

from parmpm.core.cache_key import install as _key_cache_to_sources

_key_cache_to_sources()  # before any kernel below is decorated

JIT_OPTIONS = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")

kernel = njit(**JIT_OPTIONS)
inline_kernel = njit(inline="always", **JIT_OPTIONS)
loop_kernel = njit(_nrt=False, **JIT_OPTIONS)
helper_kernel = njit(_nrt=False, forceinline=True, **JIT_OPTIONS)
