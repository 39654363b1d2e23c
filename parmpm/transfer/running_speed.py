"""What a specialised G2P keeps of each particle's stress update for the next step: the running
largest ``c_p + |v_p|`` (the CFL step), or, with a fixed step (``time.dt``), only whether
everything stayed finite.

The CFL speed costs a square root (and, for neo-Hookean, one after ``ln J``) per particle, the
largest single item of the stress update (``docs/results/throughput.md``). A run with a fixed
step does not need it every step: ``Material.cfl`` is None there, and :func:`running_speed`
compiles to a finiteness test on quantities the update has anyway, so LLVM drops the wave speed
from the loop. The driver measures the speed on its own every few steps
(:class:`parmpm.step.stepper.Stepper`) for the warning of a fixed step past the CFL one.

An overload inlined by LLVM, as :func:`parmpm.transfer.rows.row`, and for the same reason.
"""
import math

from numba import types
from numba.extending import overload

from parmpm.core.jit import HELPER_OVERLOAD_OPTIONS


def _finite_only(cfl, vmax, c, v2, check, J):
    # check − check is 0 for a finite check, NaN for ±inf or NaN (strict IEEE: LLVM keeps it);
    # J ≤ 0 (an inverted particle) is what makes both laws' c infinite
    return vmax if J > 0.0 and check - check == 0.0 else math.inf


def _largest(cfl, vmax, c, v2, check, J):
    s = c + math.sqrt(v2)
    if not (s <= vmax):
        return s if s == s else math.inf
    return vmax


def running_speed(cfl, vmax, c, v2, check, J):
    """The running maximum ``vmax`` after a particle of wave speed ``c``, squared speed ``v2``,
    ``check`` (a sum of its new stress and velocity components) and ``J = det F``: with ``cfl``
    (True) the largest ``c + √v2`` (``inf`` once one is NaN; both laws give ``c = inf`` at
    ``J ≤ 0``); without (None) ``vmax`` while ``check`` is finite and ``J > 0``, else ``inf``:
    the same runs stop, at the same step."""
    return (_finite_only if cfl is None else _largest)(cfl, vmax, c, v2, check, J)


@overload(running_speed, jit_options=HELPER_OVERLOAD_OPTIONS)
def _running_speed(cfl, vmax, c, v2, check, J):
    return _finite_only if isinstance(cfl, types.NoneType) else _largest
