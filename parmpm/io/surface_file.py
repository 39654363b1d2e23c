"""Reading a closed triangulated surface (a body's boundary in 3D) from an STL, OBJ or PLY file.

STL (ASCII or binary) and PLY are read with meshio; OBJ with the small reader below, because
meshio's OBJ reader fails on the common files whose faces carry texture or normal indices
(``f 1/1/1 2/3/1 ...``) with a count of ``vt`` unlike the count of ``v``, and misreads OBJ's
negative (relative) indices. Quads and larger polygons are split into a fan of triangles, which
keeps the enclosed volume of a planar convex polygon.

Every problem a user can cause is one line naming the file: missing, a directory, empty or
unreadable, no triangles, a vertex that is not finite, a triangle index out of range, points that
are not 3D. Whether the triangles close a volume is :func:`parmpm.geometry.surface.check_surface`'s
question, not the reader's.
"""
from __future__ import annotations

import contextlib
import io
import warnings
from pathlib import Path

import numpy as np

from parmpm.core.errors import SceneError

FORMATS = {".stl": "stl", ".obj": "obj", ".ply": "ply"}
#: an OBJ index at least this large fits no int64 array (and no file's vertex count)
INDEX_LIMIT = 2**63


def read_surface(path) -> tuple[np.ndarray, np.ndarray]:
    """The vertices (n, 3) float64 and triangles (m, 3) int64 (0-based) of the surface in ``path``."""
    path = Path(path)
    fmt = _format(path)
    if fmt == "obj":
        points, faces = _read_obj(path)
    else:
        points, faces = _read_meshio(path, fmt)
    return _checked(path, points, faces)


def _fail(path: Path, problem: str) -> SceneError:
    return SceneError(f"surface file '{path}': {problem}")


def _format(path: Path) -> str:
    if not path.exists():
        raise _fail(path, "not found; expected an existing STL, OBJ or PLY file")
    if path.is_dir():
        raise _fail(path, "is a directory; expected an STL, OBJ or PLY file")
    if not path.is_file():  # a FIFO would block open() until something writes to it
        raise _fail(path, "is not a regular file (a FIFO, device or socket); expected an STL, "
                    "OBJ or PLY file")
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise _fail(path, f"unknown extension {path.suffix!r}; expected .stl, .obj or .ply")
    try:
        size = path.stat().st_size
        with open(path, "rb"):
            pass
    except OSError as e:
        raise _fail(path, f"cannot be opened ({e.strerror})") from None
    if size == 0:
        raise _fail(path, f"is empty; expected a triangulated surface in {fmt.upper()} format")
    return fmt


def _read_meshio(path: Path, fmt: str) -> tuple[np.ndarray, list[np.ndarray]]:
    """meshio's points and polygon blocks; its prints and exits become one error line."""
    import meshio

    if fmt == "ply":
        _ply_header(path)
    sink = io.StringIO()
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(sink), \
                contextlib.redirect_stderr(sink):
            warnings.simplefilter("ignore")
            mesh = meshio.read(path, file_format=fmt)
    except (Exception, SystemExit) as e:  # meshio calls sys.exit on some bad files
        why = ("malformed or truncated" if isinstance(e, SystemExit) or not str(e).strip()
               else str(e).strip().splitlines()[0][:120])
        raise _fail(path, f"cannot be read as {fmt.upper()} ({why}); expected a valid "
                    f"{fmt.upper()} surface") from None
    faces = [np.asarray(c.data) for c in mesh.cells
             if c.type in ("triangle", "quad") or c.type.startswith("polygon")]
    return np.asarray(mesh.points), faces


def _ply_header(path: Path) -> None:
    """A PLY file must start with 'ply' and end its header: meshio loops forever on one that
    stops inside the header."""
    with open(path, "rb") as f:
        head = f.read(1 << 20)
    if not head.startswith(b"ply") or b"end_header" not in head:
        raise _fail(path, "has no PLY header ('ply' ... 'end_header'); expected a valid PLY "
                    "surface")


def _read_obj(path: Path) -> tuple[np.ndarray, list[np.ndarray]]:
    """``v x y z`` and ``f i j k ...`` lines (``i/t/n`` and negative indices allowed)."""
    data = path.read_bytes()
    if b"\0" in data:
        raise _fail(path, "holds binary bytes (NUL); expected an OBJ text file")
    text = data.decode("utf-8", errors="replace")  # names and comments may be in any encoding
    points, faces = [], []
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split("#", 1)[0].split()
        if not words or words[0] not in ("v", "f"):
            continue
        try:
            if words[0] == "v":
                if len(words) not in (4, 5, 7):  # x y z [w] or x y z r g b
                    raise ValueError(f"{len(words) - 1} coordinates, expected 3")
                points.append([float(w) for w in words[1:4]])
            else:
                index = [_index(path, number, w.split("/", 1)[0], len(points)) for w in words[1:]]
                if len(index) < 3 or 0 in index:
                    raise ValueError("a face needs 3 or more nonzero indices")
                faces.append([i - 1 if i > 0 else len(points) + i for i in index])
        except ValueError as e:
            raise _fail(path, f"line {number} {line.strip()[:40]!r} is not valid OBJ ({e}); "
                        "expected 'v x y z' or 'f i j k'") from None
    blocks: dict[int, list] = {}
    for f in faces:
        blocks.setdefault(len(f), []).append(f)
    return np.asarray(points, float).reshape(-1, 3), [np.asarray(b) for b in blocks.values()]


def _index(path: Path, number: int, word: str, seen: int) -> int:
    """A face's vertex index; one that fits no int64 (no file has that many vertices) is refused
    naming the line and the value, its middle cut when long (a line may hold 10,000 digits,
    more than ``int()`` converts)."""
    digits = word.lstrip("+-")
    significant = digits.lstrip("0") if digits.isascii() and digits.isdigit() else ""
    if len(significant) <= 19 and (not significant or int(significant) < INDEX_LIMIT):
        return int(word)  # not a plain integer: int's ValueError, said with the line
    shown = word if len(word) <= 40 else f"{word[:20]}...{word[-8:]} ({len(digits)} digits)"
    raise _fail(path, f"line {number}: face index {shown} is beyond any vertex count (at most "
                f"2^63 - 1); expected an index of one of its {seen} vertices so far (1..n, or "
                "-n..-1 from the last)")


def _fan(faces: list[np.ndarray]) -> np.ndarray:
    """Polygons (k, p) split into the triangles (0, j, j+1): a quad into two."""
    tris = [f[:, [0, j, j + 1]] for f in faces if f.ndim == 2 and f.shape[1] >= 3
            for j in range(1, f.shape[1] - 1)]
    return np.concatenate(tris).astype(np.int64) if tris else np.zeros((0, 3), np.int64)


def _checked(path: Path, points: np.ndarray, faces: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    points = np.asarray(points, dtype=np.float64)
    if points.size == 0:
        points = points.reshape(0, 3)
    if points.ndim != 2 or points.shape[1] != 3:
        shape = points.shape[1:] if points.ndim == 2 else points.shape
        raise _fail(path, f"vertices have shape {shape}; expected 3D points (x, y, z)")
    triangles = _fan(faces)
    if len(triangles) == 0:
        raise _fail(path, f"holds no triangles ({len(points)} vertices); expected a closed "
                    "triangulated surface")
    if len(points) == 0:
        raise _fail(path, f"holds no vertices ({len(triangles)} triangles); expected a closed "
                    "triangulated surface")
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if bad.size:
        raise _fail(path, f"vertex {bad[0]} is {points[bad[0]].tolist()} ({bad.size} not "
                    "finite); expected finite coordinates")
    out = np.flatnonzero(((triangles < 0) | (triangles >= len(points))).any(axis=1))
    if out.size:
        t = out[0]
        raise _fail(path, f"triangle {t} refers to vertices {triangles[t].tolist()} (0-based) of "
                    f"{len(points)} ({out.size} triangles out of range); expected indices "
                    f"0..{len(points) - 1}")
    return points, triangles
