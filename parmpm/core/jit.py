"""The one place JIT flags are set: every kernel is ``@kernel``-decorated (numba, cached, strict
IEEE arithmetic so results are reproducible bit for bit), and every per-particle helper of a hot
loop is a ``@helper_kernel``.

A helper must not cost a call: a call per corner through LLVM cost ~2× in P2G. There are two ways
to remove it, and they compile very differently:

* numba-IR inlining (``inline="always"``) pastes the helper's IR into every call site and types
  it again there. A kernel whose four corners call a dozen helpers is typed as one huge function:
  the 2D CPDI2 G2P took 12 s to compile, the default scene's kernels about 27 s.
* LLVM inlining (``forceinline``): the helper is typed and compiled once per signature, then
  LLVM inlines it into the caller before optimising, so the compiler still sees one loop body.
  The same G2P compiles in 1.2–1.9 s (2026-12-01, this project's 2-core machine).

So every helper is LLVM-inlined. LLVM does not reassociate or contract floating-point
arithmetic without ``fastmath``, so the inlined code does the same operations in the same order:
results are bit for bit those of numba-IR inlining (checked on every rank case with
``run_scripts/tools/bit_identical.py``).

Helpers and particle loops run with numba's reference counting off (``_nrt=False``): with it on,
every array handed to a helper costs an atomic incref/decref pair per call that LLVM cannot
prune — 55–70 % of a generic 1D P2G's time. They may index, slice and write the arrays they are
given but never allocate or return one (allocating fails to compile, so the contract is checked):

* ``@loop_kernel``: a particle loop; its scratch comes from a ``@kernel`` wrapper;
* ``@helper_kernel``: a per-particle helper, inlined by LLVM (``forceinline``) into its caller;
* ``@hook_helper_kernel``: a helper that takes other helpers as arguments (a particle loop's
  ``support``/``scatter``/``gather`` hooks). It is not cached on disk: numba's cache index keys
  it by its argument types, a helper's type among them, and an index read in another process
  holds types whose helpers are gone (a run failed saving one, ``ReferenceError: underlying
  object has vanished``; an index written by the tests names their modules). Its callers cache
  the inlined code, so it is compiled only where a new kernel is.

Every cached one is keyed to the whole source of the package
(:mod:`parmpm.core.cache_key`): numba's own key is the kernel's file alone, and a kernel's machine code
holds the helpers it calls from other modules.
"""
from numba import njit

from parmpm.core.cache_key import install as _key_cache_to_sources

_key_cache_to_sources()  # before any kernel below is decorated

JIT_OPTIONS = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")

kernel = njit(**JIT_OPTIONS)
loop_kernel = njit(_nrt=False, **JIT_OPTIONS)
helper_kernel = njit(_nrt=False, forceinline=True, **JIT_OPTIONS)
hook_helper_kernel = njit(_nrt=False, forceinline=True, **{**JIT_OPTIONS, "cache": False})

# The flags of a ``helper_kernel`` for an ``@overload`` (a plain function jitted code may call):
# numba caches an overload with the kernel that calls it, so it takes no ``cache`` of its own.
HELPER_OVERLOAD_OPTIONS = {**{k: v for k, v in JIT_OPTIONS.items() if k != "cache"},
                           "_nrt": False, "forceinline": True}
