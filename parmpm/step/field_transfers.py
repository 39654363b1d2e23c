"""The transfers of a step with several velocity fields (a :class:`~parmpm.step.contact.
ContactPhase`: contact bodies, or a crack's two sides): which field's grid each particle fills
and reads, and what their G2P tells the migration. The stepper runs one field itself
(:meth:`parmpm.step.stepper.Stepper.p2g`, ``g2p``) and hands a step with fields here.

Two ways to split the particles: contact fields by body (each field's particles, found by
``C.boxes(k)``, through the transfers' specialised kernels with a subset), and a crack's sides
per node (``C.on_sides``: the particles near a crack through the generic loops with their side
of every node, the rest through the specialised kernels as one field).
"""
from __future__ import annotations


def p2g_fields(C, T, P, plan, grid_phase, kernels, bforce, dt, err, ledger) -> None:
    """P2G of the step ``dt`` into every field's grid sums, with their first moments where they
    cannot wait for the masses' accumulation: mirror or crack faces
    (:meth:`~parmpm.step.contact.ContactPhase.moments_where_fields_meet`). ``C`` the contact
    phase, ``T`` the transfers, ``kernels`` the kernels asked for, ``ledger`` whether an energy
    ledger reads the force rows."""
    C.split(P)
    if C.crack is not None:  # every field in one pass, each particle's per node
        T.use("generic")
        C.find_sides(T, P, plan, grid_phase.records()[0], err)
        C.on_sides(T, kernels, lambda g: T.p2g(g, bforce, dt, err, ledger), C.stacked,
                   C.stacked_near, slice(None))
        C.on_sides(T, kernels, lambda g: T.p2g_momentum(g, err, positions=True), C.stacked_x,
                   far=False)
        return
    C.late_moments = grid_phase.symmetry is None
    try:
        for k in range(C.K):
            T.subset = C.boxes(k)
            T.p2g(C.grids[k], bforce, dt, err, ledger)
            if not C.late_moments:  # else taken after the masses' accumulation
                T.p2g_momentum(C.moments[k], err, positions=True)
    finally:
        T.subset = None


def p2g_momentum_fields(C, T, kernels, dim, err) -> None:
    """MUSL's momentum re-map into every field's grid sums."""
    if C.crack is not None:
        C.on_sides(T, kernels, lambda g: T.p2g_momentum(g, err), C.stacked, C.stacked_near,
                   slice(1, 1 + dim))
        return
    try:
        for k in range(C.K):
            T.subset = C.boxes(k)
            T.p2g_momentum(C.grids[k], err)
    finally:
        T.subset = None


def g2p_fields(C, T, moves, kernels, mode, dt, err, locate, final: bool) -> float:
    """G2P in ``mode`` from every field's grid; returns the largest speed and leaves in
    ``moves.located`` the next patches the specialised kernels found, when they found every
    particle's (``final``: the step's last G2P, not MUSL's motion pass)."""
    moves.located = None
    if C.crack is not None:
        out = C.on_sides(T, kernels, lambda g: T.g2p(g, mode, dt, err, locate), C.stacked)
        if out[0][1] is not None and final:  # the specialised kernels found the next patches
            # of their particles: all, or those away from a crack
            if len(out) == 1:
                moves.located = out[0][1]
            else:
                moves.locate_rest(out[0][1], C.near_boxes[1])
        return max(speed for speed, _ in out)
    # each field's particles from its own grid; every particle is in one field's share, so the
    # fields' G2P together find every next patch, as one field's does (the migration looks
    # again only when a particle left the grid: its message names the first in canonical
    # order, which a field's share does not know)
    vmax, moved, whole = 0.0, 0, final
    try:
        for k in range(C.K):
            T.subset = C.boxes(k)
            speed, located = T.g2p(C.grids[k], mode, dt, err, locate)
            vmax = max(vmax, speed)
            if located is None or located[0] >= 0:
                whole = False
            else:
                moved += int(located[1])
    finally:
        T.subset = None
    moves.located = (-1, moved) if whole else None
    return vmax
