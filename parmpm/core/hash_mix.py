"""splitmix64's finaliser (Steele, Lea & Flood, *Fast splittable pseudorandom number generators*,
OOPSLA 2014): a 64-bit mix after which every output bit depends on every input bit.

Both repeat checks of a file body hash lattice data — mesh node numbers, particle coordinates
whose low mantissa bits are all alike — and take a hash's low bits as its slot or compare whole
hashes. A multiply alone leaves the low bits a function of the low input bits only, so a lattice's
keys pile up; this finish spreads them. One definition serves numpy (arrays of ``uint64``) and
numba (a scalar, through the ``helper_kernel`` copy), so the two checks cannot drift apart.
"""
from __future__ import annotations

import numpy as np

from parmpm.core.jit import helper_kernel


def splitmix64_finish(z):
    """The finaliser of splitmix64 on ``uint64`` ``z`` (a scalar or an array; wraps modulo 2⁶⁴)."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


splitmix64_finish_kernel = helper_kernel(splitmix64_finish)
