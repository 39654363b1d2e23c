"""Per-patch sums of per-particle addends, in a fixed order.

The run driver sums a metric's (or the energy balance's) per-particle addends patch by patch,
each patch's particles strictly in storage order, and then the patches in id order
(:func:`decomposition.ordered_sum`): the same rounding on any number of ranks.
"""
import numpy as np

from parmpm.jit import kernel


@kernel
def patch_sums(start, values):
    """(patches, k) sums of ``values`` rows over each patch's particles, strictly in order."""
    out = np.zeros((start.size - 1, values.shape[1]))
    for p in range(start.size - 1):
        for i in range(start[p], start[p + 1]):
            for c in range(values.shape[1]):
                out[p, c] += values[i, c]
    return out


__all__ = ["patch_sums"]
