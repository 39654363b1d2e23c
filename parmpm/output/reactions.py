"""The history's reaction rows: what the rigid walls (:mod:`parmpm.grid.walls`), the held
faces and node regions, and contact between fields (:mod:`parmpm.grid.contact`) did to the
bodies, read from the energy ledger's running sums (:class:`parmpm.output.energy.EnergyLedger`),
and only in scenes that have them; their columns' names: :mod:`parmpm.io.history_columns`."""
from __future__ import annotations

import numpy as np


def held(boundary) -> bool:
    """Any held face (fixed or slip; a mirror's reaction has columns of its own) or node
    region: the history reports their reaction."""
    return (any(side in ("fixed", "slip") for pair in boundary.faces for side in pair)
            or bool(boundary.fixed_regions) or bool(boundary.slip_regions))


def mirrors(spec) -> bool:
    """Whether the history has the mirror faces' columns: a symmetry or clamped face, in a
    scene without damping or loads, whose momentum the balance below would also hold."""
    return (any(side in ("symmetry", "clamped") for pair in spec.boundary.faces for side in pair)
            and spec.damping.coefficient == 0.0 and not spec.loads)


def mirror_row(ledger, dim: int, t: float, momentum, mass: float) -> list[float]:
    """The mirror columns (:func:`~parmpm.io.history_columns.mirror_columns`): the mean force
    since the last row and the impulse since the start of every mirror face together.

    A mirror acts through the folded grid, not through held nodes of its own, so its impulse is
    what the momentum balance leaves: the bodies' momentum change less gravity's impulse
    ``M ∫g dt``, the held faces' and regions', the walls' and the contact fields' (the ledger's
    sums). Exact up to round-off (without a mirror it reads 1e-13 of the momentum), first known
    at a history row, hence a mean force between rows."""
    p = np.asarray(momentum, float)[:dim]
    if ledger.momentum0 is None:
        ledger.momentum0 = [float(v) for v in p]
    other = ledger.support[:dim] + mass * ledger.g_time[:dim]
    if ledger.walls.shape[0]:
        other = other + ledger.walls[:, :dim].sum(axis=0)
    if ledger.contact.shape[0]:
        other = other + ledger.contact[:, :dim].sum(axis=0)
    impulse = p - np.asarray(ledger.momentum0) - other
    force = np.zeros(dim)
    if ledger.mirror_last is not None and t > ledger.mirror_last[0]:
        force = (impulse - np.asarray(ledger.mirror_last[1:])) / (t - ledger.mirror_last[0])
    ledger.mirror_last = [float(t)] + [float(v) for v in impulse]
    return [float(v) for v in force] + [float(v) for v in impulse]


def wall_row(ledger, dim: int, n: int) -> list[float]:
    """The wall columns (:func:`~parmpm.io.history_columns.wall_columns`) of ``n`` walls: zeros
    before the first step."""
    return _force_impulse_row(ledger.work()["walls"], ledger.wall_step, ledger.walls,
                              ledger.last_dt, dim, n)


def _force_impulse_row(work: float, step: np.ndarray, total: np.ndarray, dt: float, dim: int,
                       n: int) -> list[float]:
    """``work``, then for each of ``n`` walls or fields the last step's force (its impulse
    ``step[k]`` over ``dt``) and the impulse since the start ``total[k]``; zeros for one the
    ledger has not met yet (before the first step)."""
    row = [work]
    for k in range(n):
        fresh = k >= total.shape[0]
        row += [0.0 if fresh or dt <= 0 else step[k, a] / dt for a in range(dim)]
        row += [0.0 if fresh else total[k, a] for a in range(dim)]
    return row


def support_row(ledger, dim: int) -> list[float]:
    """The support columns (:func:`~parmpm.io.history_columns.support_columns`): the last step's
    force, the impulse."""
    dt = ledger.last_dt
    return ([ledger.support_step[a] / dt if dt > 0 else 0.0 for a in range(dim)]
            + [ledger.support[a] for a in range(dim)])


def contact_row(ledger, dim: int, n: int) -> list[float]:
    """The contact columns (:func:`~parmpm.io.history_columns.contact_columns`) of ``n``
    fields: zeros before the first step."""
    return _force_impulse_row(ledger.work()["contact"], ledger.contact_step, ledger.contact,
                              ledger.last_dt, dim, n)
