"""The end of a 2D G2P deformation update, as bookkeeping around the shared formulas: the F
update (:func:`parmpm.materials.kinematics.update_F_2d`), the law (:func:`parmpm.materials.laws.
stress_speed_2d`) and damage (:mod:`parmpm.materials.damage`) on the four entries of ``F``."""
import math

from parmpm.core.jit import helper_kernel, kernel
from parmpm.materials.kinematics import det_2d, update_F_2d
from parmpm.materials import COL_DAMAGE
from parmpm.materials.damage import damage_scalar, degrade_2d, max_stretch_2d
from parmpm.materials.laws import stress_speed_2d
from parmpm.transfer.running_speed import NO_SPEED, running_speed


@helper_kernel
def stress_damage_speed(params, row, damage, i, f00, f01, f10, f11):
    """:func:`stress_speed_2d` (the stress and ``c²``), with particle ``i``'s damage updated from
    ``F`` and its stress degraded when its material has a damage model; without one ``damage``
    is not touched (so undamaged runs are bit for bit those without the model)."""
    s00, s01, s11, c2, pv = stress_speed_2d(params, row, f00, f01, f10, f11)
    if params[row, COL_DAMAGE] != 0.0:
        D = damage_scalar(params, row, damage[i], max_stretch_2d(f00, f01, f10, f11))
        damage[i] = D
        s00, s01, s11 = degrade_2d(D, pv, s00, s01, s11)
    return s00, s01, s11, c2


@helper_kernel
def update_F_stress(run, i, l, f, v, F, stress, mat, params, damage, cfl):
    """Particle ``i``: ``F ← F + l F`` (``l = Δt L`` and ``f = F`` as 4-tuples of entries), its
    damage and (degraded) stress, and the running largest ``c_p + |v_p|`` (``run``, whose first
    entry is it: ``inf`` once one is NaN; with ``cfl`` None only the finiteness:
    :mod:`parmpm.transfer.running_speed`)."""
    n00, n01, n10, n11 = update_F_2d(l[0], l[1], l[2], l[3], f[0], f[1], f[2], f[3])
    F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1] = n00, n01, n10, n11
    s00, s01, s11, c2 = stress_damage_speed(params, mat[i], damage, i, n00, n01, n10, n11)
    stress[i, 0, 0], stress[i, 0, 1], stress[i, 1, 0], stress[i, 1, 1] = s00, s01, s01, s11
    vx, vy = v[i, 0], v[i, 1]
    return running_speed(cfl, run, c2, vx * vx + vy * vy, s00 + s01 + s11 + vx + vy,
                         det_2d(n00, n01, n10, n11))


@kernel
def stress_pass(F, mat, params, stress):
    """The stress update of every particle on its own (what G2P does after ``F``): for
    ``parmpm bench``'s "stress" line, which G2P's fused loop cannot time separately."""
    vmax = 0.0
    for i in range(F.shape[0]):
        s00, s01, s11, c2, _ = stress_speed_2d(params, mat[i], F[i, 0, 0], F[i, 0, 1], F[i, 1, 0],
                                               F[i, 1, 1])
        stress[i, 0, 0], stress[i, 0, 1], stress[i, 1, 0], stress[i, 1, 1] = s00, s01, s01, s11
        vmax = max(vmax, math.sqrt(c2))
    return vmax


@kernel
def speed_pass(v, F, mat, params):
    """The largest ``c_p + |v_p|`` of every particle on its own, by G2P's formula: what a run at a
    fixed step measures every few steps (:mod:`parmpm.step.speed_watch`)."""
    run = NO_SPEED
    for i in range(F.shape[0]):
        c2 = stress_speed_2d(params, mat[i], F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1])[3]
        run = running_speed(True, run, c2, v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1], 0.0, 1.0)
    return run[0]
