"""A checkpoint's file names, and where its part files may be: in its own ``<checkpoint>.parts/``
folder, nowhere else.

A top-level checkpoint names its parts (``/parts/file``) relative to its folder. Its digests are
keyless (they catch damage, not intent), so a crafted file can carry any names with valid
digests: joined to the folder unchecked, ``/etc/...`` or ``../../x`` would make a restart read
files anywhere, and its error ("no such file" or "not a readable HDF5 file") would tell whether
some outside path exists. So a name must be ``<checkpoint>.parts/<file>``, exactly as the writer
(:func:`parmpm.driver.checkpoint_writer.write_checkpoint`) makes it, and a part file must not be a link
that leads out of that folder; both refusals are decided from names and links alone, before any
part is opened, and read the same whether the outside path exists or not.
"""
from __future__ import annotations

import os
from pathlib import Path

from parmpm.core.errors import ParmpmError


def checkpoint_name(step: int) -> str:
    return f"checkpoint_{step:08d}.h5"


def parts_folder(path: Path) -> Path:
    """The folder of the part files of checkpoint ``path``: ``checkpoint_<step>.parts``."""
    path = Path(path)
    return path.with_name(path.name[:-3] + ".parts" if path.name.endswith(".h5") else
                          path.name + ".parts")


def part_name(k: int) -> str:
    return f"part_{k:05d}.h5"


def part_paths(path: Path, names: list[str], where: str) -> list[Path]:
    """Where the part files of checkpoint ``path`` are: each name must be ``<checkpoint>.parts/
    <file>``, as the writer makes them. Nothing else is opened (an absolute name, ``..``, another
    folder: a crafted file could otherwise read, or probe, any path), and the refusal is decided
    from the name alone, so it never tells whether some outside path exists."""
    real = Path(os.path.realpath(path)) if path.is_symlink() else path
    folder = parts_folder(real)
    paths = []
    for k, name in enumerate(names):
        head, sep, tail = name.partition("/")
        if (head != folder.name or not tail or "/" in tail or tail in (".", "..")
                or any(c in name for c in "\\\0")):
            raise ParmpmError(f"{where}: damaged or crafted: part {k} is named {name!r}, not a "
                              f"file in '{folder.name}/' (a checkpoint's parts stay in its own "
                              "parts folder)")
        paths.append(real.parent / head / tail)
    return paths


def inside(path: Path, where: str) -> None:
    """A part file must not be a link that leads out of its parts folder (the verdict is made from
    the links alone, the same whether the outside target exists or not)."""
    folder = os.path.realpath(path.parent)
    if os.path.dirname(os.path.realpath(path)) != folder:
        raise ParmpmError(f"{where}: a link that leads out of '{path.parent.name}/' (refused: a "
                          "checkpoint's parts stay in its own parts folder)")
