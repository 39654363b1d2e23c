"""Material passes over a whole particle set, outside the transfers: the largest
``c_p + |v_p|`` that sets the first time step, and the stress update on its own (G2P fuses it
into its loop; the benchmark times this pass to report the stress update's share)."""
import math

from parmpm.core.jit import loop_kernel
from parmpm.materials.laws import cauchy_stress, wave_speed


@loop_kernel
def max_speed(d, v, F, mat, params):
    """Largest ``c_p + |v_p|`` (current-configuration wave speed plus particle speed)."""
    vmax = 0.0
    for i in range(v.shape[0]):
        s = 0.0
        for a in range(d):
            s += v[i, a] * v[i, a]
        vmax = max(vmax, wave_speed(d, params[mat[i]], F[i]) + math.sqrt(s))
    return vmax


@loop_kernel
def stress_pass(d, F, mat, params, damage, stress):
    """Stress and wave speed of every particle on their own (G2P fuses them into its loop; the
    benchmark times this to report the stress update's share)."""
    vmax = 0.0
    for i in range(F.shape[0]):
        prm = params[mat[i]]
        cauchy_stress(d, prm, F[i], damage[i], stress[i])
        vmax = max(vmax, wave_speed(d, prm, F[i]))
    return vmax
