"""The end of a 3D G2P deformation update, as bookkeeping around the shared formulas: the F
update (:func:`parmpm.materials.kinematics.update_F_3d`), the law (:func:`parmpm.materials.laws.
stress_speed_3d`) and damage (:mod:`parmpm.materials.damage`) on the nine entries of ``F``."""
import math

from parmpm.core.jit import helper_kernel, kernel
from parmpm.materials.kinematics import det_3d, update_F_3d
from parmpm.materials import COL_DAMAGE
from parmpm.materials.damage import damage_scalar, degrade_3d, max_stretch_3d
from parmpm.materials.laws import stress_speed_3d
from parmpm.transfer.running_speed import NO_SPEED, running_speed


@helper_kernel
def store_stress(stress, i, s00, s01, s02, s11, s12, s22):
    """Write the symmetric stress ``σ`` of particle ``i``."""
    stress[i, 0, 0], stress[i, 0, 1], stress[i, 0, 2] = s00, s01, s02
    stress[i, 1, 0], stress[i, 1, 1], stress[i, 1, 2] = s01, s11, s12
    stress[i, 2, 0], stress[i, 2, 1], stress[i, 2, 2] = s02, s12, s22


@helper_kernel
def update_F_stress(run, i, l, f, v, F, stress, mat, params, damage, cfl):
    """Particle ``i``: ``F ← F + l F`` (``l = Δt L`` and ``f = F`` as 9-tuples of entries, row
    by row), its damage and (degraded) stress, and the running largest ``c_p + |v_p|`` (``run``,
    whose first entry is it: ``inf`` once one is NaN; with ``cfl`` None only the finiteness:
    :mod:`parmpm.transfer.running_speed`)."""
    n00, n01, n02, n10, n11, n12, n20, n21, n22 = update_F_3d(
        l[0], l[1], l[2], l[3], l[4], l[5], l[6], l[7], l[8],
        f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8])
    F[i, 0, 0], F[i, 0, 1], F[i, 0, 2] = n00, n01, n02
    F[i, 1, 0], F[i, 1, 1], F[i, 1, 2] = n10, n11, n12
    F[i, 2, 0], F[i, 2, 1], F[i, 2, 2] = n20, n21, n22
    row = mat[i]
    s00, s01, s02, s11, s12, s22, c2, pv = stress_speed_3d(params, row, n00, n01, n02, n10, n11,
                                                           n12, n20, n21, n22)
    if params[row, COL_DAMAGE] != 0.0:  # damage: touch nothing else without a model
        D = damage_scalar(params, row, damage[i],
                          max_stretch_3d(n00, n01, n02, n10, n11, n12, n20, n21, n22))
        damage[i] = D
        s00, s01, s02, s11, s12, s22 = degrade_3d(D, pv, s00, s01, s02, s11, s12, s22)
    store_stress(stress, i, s00, s01, s02, s11, s12, s22)
    vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
    return running_speed(cfl, run, c2, vx * vx + vy * vy + vz * vz,
                         s00 + s01 + s02 + s11 + s12 + s22 + vx + vy + vz,
                         det_3d(n00, n01, n02, n10, n11, n12, n20, n21, n22))


@kernel
def stress_pass(F, mat, params, stress):
    """The stress update of every particle on its own (what G2P does after ``F``): for
    ``parmpm bench``'s "stress" line, which G2P's fused loop cannot time separately."""
    vmax = 0.0
    for i in range(F.shape[0]):
        s00, s01, s02, s11, s12, s22, c2, _ = stress_speed_3d(
            params, mat[i], F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1],
            F[i, 1, 2], F[i, 2, 0], F[i, 2, 1], F[i, 2, 2])
        store_stress(stress, i, s00, s01, s02, s11, s12, s22)
        vmax = max(vmax, math.sqrt(c2))
    return vmax


@kernel
def speed_pass(v, F, mat, params):
    """The largest ``c_p + |v_p|`` of every particle on its own, by G2P's formula: what a run at a
    fixed step measures every few steps (:mod:`parmpm.step.speed_watch`)."""
    run = NO_SPEED
    for i in range(F.shape[0]):
        c2 = stress_speed_3d(params, mat[i], F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0],
                             F[i, 1, 1], F[i, 1, 2], F[i, 2, 0], F[i, 2, 1], F[i, 2, 2])[6]
        run = running_speed(True, run, c2,
                            v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2], 0.0, 1.0)
    return run[0]
