"""``history.csv`` (one row per sample, flushed as it is written, so a killed run keeps its rows),
the same columns as a table of the run's HDF5, and ``history.png``.

Written by rank 0 only; the run driver makes every write collective
(:class:`parmpm.driver.run_files.RunFiles`). Numbers are written with ``repr`` (shortest round-trip), so
the CSV holds exactly the floats the run computed: two runs agree bit for bit iff their files do.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

#: units and meaning of the fixed columns (the probes' are ``<name>.<field>[.<stat>]``)
UNITS = {"time": "s", "step": "1", "dt": "s", "kinetic": "J", "elastic": "J",
         "gravity_potential": "J", "work_gravity": "J", "work_forces": "J", "work_boundary": "J",
         "damping_dissipation": "J", "transfer_dissipation": "J", "energy_residual": "J",
         "residual_estimate": "J", "increment_work": "J",
         "mass": "kg", "damaged": "1", "frozen": "1"}


def unit_of(column: str) -> str:
    if column.startswith("momentum_"):
        return "kg m/s"
    if column.startswith("angular_momentum_"):
        return "kg m^2/s"
    return UNITS.get(column, "")


class HistoryFile:
    """``<folder>/history.csv``: the header at open, a row per :meth:`append`."""

    def __init__(self, folder: Path, columns: list[str]):
        self.path = Path(folder) / "history.csv"
        self.columns = list(columns)
        self.count = 0  # rows written; the rows themselves are only in the file (issue 28)
        self._file = open(self.path, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._csv = csv.writer(self._file)
        self._csv.writerow(self.columns)
        self._file.flush()

    def append(self, row: list[float]) -> None:
        self._csv.writerow([repr(int(v)) if c in ("step", "damaged", "frozen") else repr(v)
                            for c, v in zip(self.columns, row)])
        self._file.flush()
        self.count += 1

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

    def table(self) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
        """The rows as columns, with their units, for an HDF5 table: read back from
        ``history.csv`` (the file is the store, so a long run's history takes no memory; ``repr``
        round-trips, so the table holds the run's floats bit for bit)."""
        cols = read_history(self.path)
        for c in ("step", "damaged", "frozen"):
            cols[c] = cols[c].astype(np.int64)
        return cols, {c: {"units": unit_of(c)} for c in self.columns}


def write_table_h5(path: Path, group: str, columns: dict, attrs: dict) -> None:
    """``columns`` as 1-D datasets of ``group`` in ``path`` (a file of their own)."""
    import h5py

    tmp = Path(path).with_name(Path(path).name + ".tmp")
    with h5py.File(tmp, "w") as f:
        g = f.create_group(group)
        for name, values in columns.items():
            ds = g.create_dataset(name, data=values)
            for key, value in attrs.get(name, {}).items():
                ds.attrs[key] = value
    tmp.replace(path)


def read_history(path) -> dict[str, np.ndarray]:
    """``history.csv`` as ``{column: array}``."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.array(rows[1:], float).reshape(len(rows) - 1, len(rows[0]))
    return {c: body[:, j] for j, c in enumerate(header)}


def plot_history(columns: dict[str, np.ndarray], png: Path, title: str) -> bool:
    """Energies (and the probes, if any) against time; False when matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    t = columns["time"]
    probes = [c for c in columns if "." in c]
    fig, axes = plt.subplots(1 + bool(probes), 1, figsize=(7, 3.6 * (1 + bool(probes))),
                             sharex=True, squeeze=False)
    ax = axes[0, 0]
    k, psi, ug = columns["kinetic"], columns["elastic"], columns["gravity_potential"]
    for label, y, style in (("kinetic K", k, "-"), ("elastic Ψ", psi, "-"),
                            ("gravity U_g", ug, "-"), ("K + Ψ + U_g", k + psi + ug, "k-"),
                            ("transfer dissipation", columns["transfer_dissipation"], "--"),
                            ("boundary work", columns["work_boundary"], ":"),
                            ("damping", columns["damping_dissipation"], ":"),
                            ("residual", columns["energy_residual"], "r-")):
        if np.any(y != 0):
            ax.plot(t, y, style, label=label, lw=1.2)
    ax.set_ylabel("energy (J)")
    ax.legend(fontsize=8, ncol=2)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if probes:
        ax = axes[1, 0]
        for c in probes:
            ax.plot(t, columns[c], label=c, lw=1.2)
        ax.set_ylabel("probes")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return True
