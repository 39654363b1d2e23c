"""What a specialised G2P keeps of each particle's stress update for the next step: the running
largest ``c_p + |v_p|`` (the CFL step), or, with a fixed step (``time.dt``), only whether
everything stayed finite.

The CFL speed costs two square roots per particle (``c = √c²`` and ``|v| = √v²``; for
neo-Hookean ``c²`` follows ``ln J``), the largest single item of the stress update
(``docs/results/throughput.md``). Two ways to pay less, both exact:

* **Most particles cannot raise the maximum.** The running state is ``(vmax, c²*, v²*)``, the
  squares of the particle that set ``vmax``. A particle with ``c² ≤ c²*`` and ``v² ≤ v²*`` has
  ``√c² + √v² ≤ vmax`` in floating point too (a correctly rounded square root and sum are
  monotone), so it is skipped without a square root; any other is measured as before. The
  result is bit for bit the maximum over every particle; in a body whose state varies little
  (the benchmark block: every particle alike) almost every particle is skipped.
* **A run with a fixed step does not need it every step**: ``Material.cfl`` is None there, and
  :func:`running_speed` compiles to a finiteness test on quantities the update has anyway, so
  LLVM drops the wave speed from the loop. The driver measures the speed on its own every few
  steps (:class:`parmpm.step.stepper.Stepper`) for the warning of a fixed step past the CFL one.

An overload inlined by LLVM, as :func:`parmpm.transfer.rows.row`, and for the same reason.
"""
import math

from numba import types
from numba.extending import overload

from parmpm.core.jit import HELPER_OVERLOAD_OPTIONS


#: the running state before the first particle: no speed yet, and no particle's squares
#: (every ``c²``, ``v²`` is ≥ 0, so none is taken for dominated)
NO_SPEED = (0.0, -1.0, -1.0)


def _finite_only(cfl, run, c2, v2, check, J):
    # check − check is 0 for a finite check, NaN for ±inf or NaN (strict IEEE: LLVM keeps it);
    # J ≤ 0 (an inverted particle) is what makes both laws' c infinite
    return run if J > 0.0 and check - check == 0.0 else (math.inf, run[1], run[2])


def _largest(cfl, run, c2, v2, check, J):
    vmax, c2_top, v2_top = run
    if c2 <= c2_top and v2 <= v2_top:  # dominated (NaN never is)
        return run
    s = math.sqrt(c2) + math.sqrt(v2)
    if not (s <= vmax):
        return (s, c2, v2) if s == s else (math.inf, math.inf, math.inf)
    return run


def running_speed(cfl, run, c2, v2, check, J):
    """The running state ``run = (vmax, c²*, v²*)`` (start from :data:`NO_SPEED`) after a
    particle of squared wave speed ``c2``, squared speed ``v2``, ``check`` (a sum of its new
    stress and velocity components) and ``J = det F``: with ``cfl`` (True) ``vmax`` is the
    largest ``√c2 + √v2`` (``inf`` once one is NaN; both laws give ``c² = inf`` at ``J ≤ 0``);
    without (None) ``vmax`` while ``check`` is finite and ``J > 0``, else ``inf``: the same runs
    stop, at the same step."""
    return (_finite_only if cfl is None else _largest)(cfl, run, c2, v2, check, J)


@overload(running_speed, jit_options=HELPER_OVERLOAD_OPTIONS)
def _running_speed(cfl, run, c2, v2, check, J):
    return _finite_only if isinstance(cfl, types.NoneType) else _largest
