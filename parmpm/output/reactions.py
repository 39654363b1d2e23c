"""The history's reaction rows: what the rigid walls (:mod:`parmpm.grid.walls`), the held
faces and node regions, and contact between fields (:mod:`parmpm.grid.contact`) did to the
bodies, read from the energy ledger's running sums (:class:`parmpm.output.energy.EnergyLedger`),
and only in scenes that have them; their columns' names: :mod:`parmpm.io.history_columns`."""
from __future__ import annotations

import numpy as np


def held(boundary) -> bool:
    """Any held face or node region: the history reports their reaction."""
    return (any(side != "free" for pair in boundary.faces for side in pair)
            or bool(boundary.fixed_regions) or bool(boundary.slip_regions))


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
