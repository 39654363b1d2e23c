"""Particle files: a body given as points, each with its own volume, so that another code's
output or a parmpm run's can start a run (issue 30)::

    from parmpm.io.particle_file import read_particle_file
    p = read_particle_file("bar.csv", dim=2)     # ParticleData: x (N, 2), volume (N,), ...
    log.info(p.describe())

The format follows the suffix (case-insensitive):

==================  ===================================================================
``.csv``            a header row naming the columns (:mod:`~parmpm.io.particle_file.table`)
``.npz``            named arrays (:mod:`~parmpm.io.particle_file.arrays`)
``.h5``, ``.hdf5``  the same arrays as datasets at the root; or a parmpm snapshot series
                    or checkpoint, told by its ``format`` attribute
                    (:mod:`~parmpm.io.particle_file.runs`)
``.xdmf``           a snapshot series' index: its ``.h5`` is read
==================  ===================================================================

Every file gives positions and volumes (required) and, optionally, velocities, material names
and deformation gradients, in the file's row order (a parmpm run's files: global-id order), so
the seeding order never depends on the ranks. Every problem is one :class:`SceneError` line
naming the file, the column or dataset, the row and the value.
"""
from __future__ import annotations

from pathlib import Path

from parmpm.io.particle_file.data import MAX_PARTICLES, ParticleData, fail

__all__ = ["MAX_PARTICLES", "ParticleData", "SUFFIXES", "read_particle_file"]

SUFFIXES = (".csv", ".npz", ".h5", ".hdf5", ".xdmf")


def _path(label: str, path: Path) -> Path:
    """``path`` if it names a readable, non-empty file of a known suffix."""
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        fail(label, f"unknown suffix '{path.suffix}'; expected one of {', '.join(SUFFIXES)}")
    if suffix == ".xdmf":
        path = path.with_suffix(".h5")
    if path.is_dir():
        fail(label, "is a directory; expected a file")
    if not path.exists():
        fail(label, f"no such file{' (the series ' + path.name + ')' if suffix == '.xdmf' else ''}")
    try:
        size = path.stat().st_size
    except OSError as exc:
        fail(label, f"cannot read: {exc.strerror or exc}")
    if size == 0:
        fail(label, "is empty (0 bytes); expected particles")
    return path


def _read_h5(label: str, path: Path, dim: int, step: int | None) -> ParticleData:
    import h5py

    from parmpm.io.checkpoint.format import FORMAT as CHECKPOINT
    from parmpm.io.particle_file.arrays import read_root
    from parmpm.io.particle_file.runs import read_checkpoint, read_snapshot
    from parmpm.io.xdmf.layout import FORMAT as SNAPSHOTS

    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        fail(label, f"is not a readable HDF5 file ({str(exc).splitlines()[0]})")
    with f:
        kind = f.attrs.get("format")
        if kind not in (SNAPSHOTS, CHECKPOINT):
            if step is not None:
                fail(label, f"holds one set of particles (no steps), so step={step} does not apply")
            return read_root(label, f, dim)
    if kind == SNAPSHOTS:
        return read_snapshot(label, path, dim, step)
    return read_checkpoint(label, path, dim, step)


def read_particle_file(path, dim: int, *, step: int | None = None) -> ParticleData:
    """The particles of the file at ``path`` for a ``dim``-D scene (module doc: the formats).
    ``step``: which step of a parmpm snapshot series (the run's step number; default the last)
    or checkpoint (must be its step) to read; other files have no steps."""
    p = Path(path)
    label = f"particle file '{p}'"
    if dim not in (1, 2, 3):
        raise ValueError(f"dim = {dim!r}, expected 1, 2 or 3")
    p = _path(label, p)
    suffix = p.suffix.lower()
    if suffix == ".csv":
        from parmpm.io.particle_file.fast_table import read_csv

        if step is not None:
            fail(label, f"is a CSV table (no steps), so step={step} does not apply")
        return read_csv(label, p, dim)
    if suffix == ".npz":
        from parmpm.io.particle_file.arrays import read_npz

        if step is not None:
            fail(label, f"is a .npz archive (no steps), so step={step} does not apply")
        return read_npz(label, p, dim)
    return _read_h5(label, p, dim, step)
