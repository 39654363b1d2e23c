"""splitmix64's finaliser against the generator's published outputs, and its numba copy against
its numpy form."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from parmpm.core.hash_mix import splitmix64_finish, splitmix64_finish_kernel

GOLDEN = np.uint64(0x9E3779B97F4A7C15)
# splitmix64 seeded with 0: its first outputs, as printed by the reference C implementation
# (Vigna's splitmix64.c) and by every port that tests against it
SEED_0 = (0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F, 0xF88BB8A8724C81EC)


def test_the_generator_seeded_with_zero_gives_its_published_outputs():
    states = GOLDEN * np.arange(1, 5, dtype=np.uint64)  # the state after 1-4 increments
    assert [int(v) for v in splitmix64_finish(states)] == list(SEED_0)


@njit
def _through_a_kernel(z):
    return splitmix64_finish_kernel(z)


@settings(deadline=None)  # the first example compiles the kernel
@given(st.integers(0, 2**64 - 1))
def test_the_kernel_is_the_numpy_form(z):
    got = _through_a_kernel(np.uint64(z))
    assert int(got) == int(splitmix64_finish(np.array([z], dtype=np.uint64))[0])


def test_a_lattice_fills_the_low_bits():
    """The reason for the finish: consecutive multiples of 2^20 (all low bits zero) land in all
    1024 ten-bit slots nearly evenly, where their raw values use one slot."""
    z = np.arange(1 << 14, dtype=np.uint64) << np.uint64(20)
    slots = splitmix64_finish(z) & np.uint64(1023)
    assert np.unique(z & np.uint64(1023)).size == 1
    counts = np.bincount(slots.astype(np.int64), minlength=1024)
    assert counts.min() >= 2 and counts.max() <= 40  # Poisson(16): 40 is ~5 sigma
