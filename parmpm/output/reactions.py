"""The history's reaction columns: what the rigid walls (:mod:`parmpm.grid.walls`) and the held
faces and node regions did to the bodies, read from the energy ledger's running sums
(:class:`parmpm.output.energy.EnergyLedger`), and only in scenes that have them."""
from __future__ import annotations

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
    row = [ledger.work()["walls"]]
    dt = ledger.last_dt
    for w in range(n):
        fresh = w >= ledger.walls.shape[0]
        row += [0.0 if fresh or dt <= 0 else ledger.wall_step[w, a] / dt for a in range(dim)]
        row += [0.0 if fresh else ledger.walls[w, a] for a in range(dim)]
    return row


def support_row(ledger, dim: int) -> list[float]:
    """The support columns (:func:`support_columns`): the last step's force, the impulse."""
    dt = ledger.last_dt
    return ([ledger.support_step[a] / dt if dt > 0 else 0.0 for a in range(dim)]
            + [ledger.support[a] for a in range(dim)])
