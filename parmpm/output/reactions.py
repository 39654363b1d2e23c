"""The history's reaction columns: what the rigid walls (:mod:`parmpm.grid.walls`), the held
faces and node regions, and contact between fields (:mod:`parmpm.grid.contact`) did to the
bodies, read from the energy ledger's running sums (:class:`parmpm.output.energy.EnergyLedger`),
and only in scenes that have them."""
from __future__ import annotations

import numpy as np

#: component letters of vector columns (as :mod:`parmpm.output.history`'s)
AXES = "xyz"


def held(boundary) -> bool:
    """Any held face or node region: the history reports their reaction."""
    return (any(side != "free" for pair in boundary.faces for side in pair)
            or bool(boundary.fixed_regions) or bool(boundary.slip_regions))


def wall_columns(dim: int, walls: tuple[str, ...]) -> list[str]:
    """With walls: the work they did (J), and per wall the force it exerted on the bodies over
    the last step (N) and the impulse it gave them since the start (N s)."""
    if not walls:
        return []
    return ["work_walls"] + [f"{name}.{kind}_{AXES[a]}" for name in walls
                             for kind in ("force", "impulse") for a in range(dim)]


def support_columns(dim: int) -> list[str]:
    """With held faces or node regions: the force they exerted on the bodies over the last step
    (N) and their impulse since the start (N s), all of them together."""
    return ([f"support.force_{AXES[a]}" for a in range(dim)]
            + [f"support.impulse_{AXES[a]}" for a in range(dim)])


def wall_row(ledger, dim: int, n: int) -> list[float]:
    """The wall columns (:func:`wall_columns`) of ``n`` walls: zeros before the first step."""
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
    """The support columns (:func:`support_columns`): the last step's force, the impulse."""
    dt = ledger.last_dt
    return ([ledger.support_step[a] / dt if dt > 0 else 0.0 for a in range(dim)]
            + [ledger.support[a] for a in range(dim)])


def contact_columns(dim: int, names: tuple[str, ...]) -> list[str]:
    """With contact between velocity fields (``names``: each field's, in field order): the
    contact's work (J), and per field the contact force on it over the last step (N) and the
    impulse since the start (N s)."""
    if not names:
        return []
    return ["work_contact"] + [f"{name}.{kind}_{AXES[a]}" for name in names
                               for kind in ("force", "impulse") for a in range(dim)]


def contact_row(ledger, dim: int, n: int) -> list[float]:
    """The contact columns (:func:`contact_columns`) of ``n`` fields: zeros before the first
    step."""
    return _force_impulse_row(ledger.work()["contact"], ledger.contact_step, ledger.contact,
                              ledger.last_dt, dim, n)
