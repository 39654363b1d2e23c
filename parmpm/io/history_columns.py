"""The history's named columns (``history.csv`` and the run's HDF5 history table): a probe's, a
wall's, the held boundary's and the contact fields'.

One definition for the run that writes them (:class:`parmpm.output.history.History`) and for
the scene check that refuses two names writing the same column
(:func:`parmpm.scene.history.check_columns`): ``history.csv`` would hold that column twice and
the HDF5 table, keyed by name, only one of them.
"""
from __future__ import annotations

from collections.abc import Sequence

#: component letters of vector columns (as :mod:`parmpm.output.history`'s)
AXES = "xyz"


def reaction_columns(name: str, dim: int) -> list[str]:
    """A wall's, the supports' or a contact field's: the force on the bodies over the last step
    (N) and the impulse since the start (N s)."""
    return [f"{name}.{kind}_{AXES[a]}" for kind in ("force", "impulse") for a in range(dim)]


def probe_columns(name: str, fields: Sequence[str], stats: Sequence[str]) -> list[str]:
    """A probe's: ``<name>.<field>`` for a point probe (no ``stats``), else
    ``<name>.<field>.<stat>``."""
    if not stats:
        return [f"{name}.{f}" for f in fields]
    return [f"{name}.{f}.{s}" for f in fields for s in stats]


def wall_columns(dim: int, walls: Sequence[str]) -> list[str]:
    """With walls: the work they did (J), and every wall's reaction columns."""
    if not walls:
        return []
    return ["work_walls"] + [c for name in walls for c in reaction_columns(name, dim)]


def support_columns(dim: int) -> list[str]:
    """With held faces or node regions: their reaction, all of them together."""
    return reaction_columns("support", dim)


def mirror_columns(dim: int) -> list[str]:
    """With symmetry or clamped faces (no damping, no loads): their reaction, all together."""
    return reaction_columns("mirror", dim)


def contact_names(names: Sequence[str], fields: int, cracks: bool) -> tuple[str, ...]:
    """Every velocity field's history name: its given name or ``contact<k>``, and with cracks
    each one's far side, ``<name>_far``, after them all."""
    base = tuple(names) or tuple(f"contact{k}" for k in range(fields))
    return base + (tuple(f"{n}_far" for n in base) if cracks else ())


def contact_columns(dim: int, names: Sequence[str]) -> list[str]:
    """With contact between velocity fields (``names``: each field's, in field order): the
    contact's work (J), and every field's reaction columns."""
    if not names:
        return []
    return ["work_contact"] + [c for name in names for c in reaction_columns(name, dim)]


def repeated(groups: Sequence[Sequence[str]]) -> tuple[str, int, int] | None:
    """The first column written twice: ``(column, earlier, later)``, the indices in ``groups``
    (each a source's columns) of its two sources, equal when one source writes it twice; None
    when every column is written once."""
    owner: dict[str, int] = {}
    for j, columns in enumerate(groups):
        for column in columns:
            if column in owner:
                return column, owner[column], j
            owner[column] = j
    return None
