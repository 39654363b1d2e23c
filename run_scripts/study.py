"""What every study script shares: MPI-aware case runs, CSV rows, figures, argument defaults.

A study is a loop over cases (scene + overrides); each case is one collective
:class:`parmpm.Simulation` run on all ranks of ``COMM_WORLD`` (so ``mpirun -n 2 python
run_scripts/<study>.py`` gives results identical to one rank: the solver is bit-identical on any
rank count). Only rank 0 writes the CSV and the PNGs. Any exception on any rank aborts every
rank (``main_guard``), so a study never hangs under mpirun.

Outputs: ``--out`` (default ``run_scripts/out/<study>``) gets the CSV and the figures;
``--figures DIR`` puts the figures elsewhere. Only ``make figures`` (run_scripts/tools/make_figures.py,
which passes ``--figures docs/figures``) writes the documentation's committed figures: a study run by
hand, or by the tests, never overwrites them.

Methods: :data:`METHODS` names every method the studies compare (an interpolator with a
transfer, e.g. ``bspline_apic`` = quadratic B-splines with APIC), with its scene overrides and
its colour and marker on every chart; adding a method there adds it to every study's full run.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import math
import shutil
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
#: the documentation's figures: written only when asked (``--figures``; ``make figures`` asks)
FIGURES = ROOT / "docs" / "figures"


@dataclass(frozen=True)
class Method:
    """One method a study compares: an interpolator and a particle–grid transfer, the update
    order ``method.update = "auto"`` gives it, and how the charts draw it."""
    key: str            # the study's name for it: CSV ``method`` column, case ids, ``--methods``
    interpolator: str   # ``method.interpolator``
    transfer: str       # ``method.transfer``: "flip" | "apic" | "mls"
    update: str         # what ``method.update = "auto"`` resolves to (parmpm.driver.simulation)
    label: str
    colour: str
    marker: str

    def overrides(self) -> list[str]:
        """Scene overrides selecting this method (``method.transfer`` only when not the default)."""
        out = [f"method.interpolator={self.interpolator}"]
        if self.interpolator == "bspline":  # the studies' scenes as measured: held regions kept
            out.append("boundary.regions_with_splines=true")
        return out + ([f"method.transfer={self.transfer}"] if self.transfer != "flip" else [])


#: Every method the studies know, in chart order. A study runs all of them unless it says
#: otherwise (``METHOD_KEYS``), so a new method is one line here.
METHODS = {m.key: m for m in (
    Method("mpm", "mpm", "flip", "musl", "MPM", "tab:gray", "s"),
    Method("ugimp", "ugimp", "flip", "musl", "uGIMP", "tab:green", "^"),
    Method("cpgimp", "cpgimp", "flip", "musl", "cpGIMP", "tab:orange", "D"),
    Method("cpdi", "cpdi", "flip", "usl", "CPDI", "tab:blue", "o"),
    Method("bspline", "bspline", "flip", "musl", "B-spline", "tab:purple", "v"),
    Method("bspline_apic", "bspline", "apic", "musl", "B-spline APIC", "tab:red", "P"),
    Method("bspline_mls", "bspline", "mls", "musl", "B-spline MLS", "tab:brown", "*"),
    Method("cpdi2", "cpdi2", "flip", "usl", "CPDI2", "tab:cyan", "X"),
)}
METHOD_KEYS = tuple(METHODS)


def method_keys(text: str | None, allowed=METHOD_KEYS) -> tuple[str, ...]:
    """The comma-separated method keys of a ``--methods`` argument (all of ``allowed`` when
    None or empty); an unknown key is an error."""
    keys = tuple(k.strip() for k in (text or "").split(",") if k.strip()) or tuple(allowed)
    bad = [k for k in keys if k not in allowed]
    if bad:
        raise SystemExit(f"--methods: unknown {', '.join(bad)} (choose from {', '.join(allowed)})")
    return keys


def world():
    from decomposition import world as _world
    return _world()


def mpirun() -> str | None:
    """The ``mpirun`` beside this Python (the venv's MPICH wheel), else the one on PATH, else None."""
    beside = Path(sys.executable).parent / "mpirun"
    return str(beside) if beside.exists() else shutil.which("mpirun")


def is_root(comm) -> bool:
    return comm.Get_rank() == 0


def parser(doc: str) -> argparse.ArgumentParser:
    """Arguments every study takes: ``--quick`` (small and fast, what the tests run), ``--out``
    (CSV folder) and ``--figures`` (PNG folder)."""
    p = argparse.ArgumentParser(description=doc.strip().splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="small grids and few cases (seconds)")
    p.add_argument("--out", type=Path, default=None,
                   help="folder for the CSV and the PNGs (default run_scripts/out/<study>)")
    p.add_argument("--figures", type=Path, default=None,
                   help="folder for the PNGs (default: --out; make figures gives docs/figures)")
    return p


def folders(args, study: str) -> tuple[Path, Path]:
    """(csv folder, figure folder) for ``args`` (see the module docstring)."""
    out = args.out or ROOT / "run_scripts" / "out" / study
    figs = args.figures or out
    return Path(out), Path(figs)


@contextlib.contextmanager
def scratch_folder(comm, prefix: str):
    """A temporary folder shared by every rank (rank 0 makes it and removes it afterwards)."""
    path = Path(comm.bcast(tempfile.mkdtemp(prefix=prefix) if is_root(comm) else None))
    try:
        yield path
    finally:
        if is_root(comm):
            shutil.rmtree(path, ignore_errors=True)


def select_cases(cases: list, patterns: str | None) -> list:
    """The cases whose ``id`` matches one of the comma-separated glob ``patterns`` (all when
    None); a pattern list matching nothing is an error."""
    import fnmatch

    if patterns:
        pats = [p.strip() for p in patterns.split(",") if p.strip()]
        cases = [c for c in cases if any(fnmatch.fnmatchcase(c.id, p) for p in pats)]
    if not cases:
        raise SystemExit(f"no case matches --cases {patterns!r}")
    return cases


def wrote(path: Path) -> str:
    """``wrote PATH`` (with its size for a PNG), for a study's last lines."""
    path = Path(path)
    return f"wrote {path}" + (f" ({path.stat().st_size // 1024} KB)" if path.suffix == ".png" else "")


def run_case(scene, overrides=(), comm=None, observers=(), out_dir=None) -> tuple[dict, float]:
    """Run one case on every rank of ``comm`` with output files off; returns (summary, wall s).
    ``scene`` is a built-in name, a TOML path or a :class:`parmpm.Scene`; ``overrides`` apply to
    any of them."""
    import parmpm
    from parmpm.driver.warm_up import compile_first

    overrides = list(overrides) + ["output.snapshots=false", "output.figure=false"]
    if isinstance(scene, parmpm.Scene):
        scene = scene_with(scene, overrides)
    else:
        scene = parmpm.load_scene(scene, overrides)
    comm = comm if comm is not None else world()
    with contextlib.ExitStack() as stack:
        if out_dir is None:
            out_dir = stack.enter_context(scratch_folder(comm, "parmpm-study-"))
        # a study owns its folders: a rerun replaces its own earlier case
        sim = parmpm.Simulation(scene, out_dir, quiet=True, comm=comm, overwrite=True,
                                warm_up=compile_first)
        sim.observers.extend(observers)
        comm.Barrier()
        t0 = time.perf_counter()
        summary = sim.run()
        wall = time.perf_counter() - t0
    from decomposition import allreduce_max
    return summary, float(allreduce_max(comm, np.array([wall]))[0])


def write_csv(path: Path, rows: list[dict], comm=None) -> None:
    """Rank 0 writes ``rows`` (dicts with the same keys) as CSV; floats with full precision."""
    if comm is not None and not is_root(comm):
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = list(rows[0]) if rows else []
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: _cell(v) for k, v in r.items()})


def _cell(v):
    if isinstance(v, float):
        return "" if not math.isfinite(v) else repr(v)
    if v is None:
        return ""
    return v


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def figure(nrows=1, ncols=1, size=(6.4, 4.8)):
    """(fig, axes) on an Agg canvas (no pyplot state, headless)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=130)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return path


def observed_orders(h, err) -> list[float]:
    """``log2``-style observed orders ``log(e_i/e_{i+1}) / log(h_i/h_{i+1})`` between successive
    resolutions (Firedrake's convergence tests)."""
    h, err = np.asarray(h, float), np.asarray(err, float)
    return [float(np.log(err[i] / err[i + 1]) / np.log(h[i] / h[i + 1])) for i in range(len(h) - 1)]


def pareto_front(cost, err) -> np.ndarray:
    """Indices of the points no other point beats in both cost and error (sorted by cost)."""
    cost, err = np.asarray(cost, float), np.asarray(err, float)
    order = np.lexsort((err, cost))
    front, best = [], math.inf
    for i in order:
        if err[i] < best:
            front.append(int(i))
            best = err[i]
    return np.asarray(front, int)


def main_guard(main) -> None:
    """Run ``main()``; an exception on any rank prints its traceback and aborts every rank."""
    comm = world()
    try:
        code = main()
    except SystemExit:
        raise
    except BaseException:
        traceback.print_exc()
        sys.stderr.flush()
        if comm.Get_size() > 1:
            comm.Abort(1)
        sys.exit(1)
    sys.exit(code or 0)


def manufactured_scene(dim: int, cells: int, interpolator: str = "cpdi", update: str = "auto",
                       ppc: int = 2, amplitude: float = 0.05, cfl: float = 0.2,
                       periods: float = 1.0, lcr: str = "none", patch_size: int | None = None,
                       transfer: str = "flip", faces: str = "symmetry"):
    """The axis-aligned manufactured solution (the built-in ``manufactured`` scene, any
    dimension): unit cube of ``cells`` cells per axis, mirror faces (``faces = "symmetry"``,
    :mod:`parmpm.grid.symmetry`, the exterior layer auto) or, as before, two cells of room on each
    side held by slip regions on and beyond the faces (``faces = "slip_regions"``: first order
    for the B-spline); Uintah's parameters (E = 1e4, ν = 0.3, ρ0 = 1: period 0.02 s).
    ``interpolator`` may also be a key of :data:`METHODS` (e.g. ``"bspline_apic"``), which sets
    ``transfer`` too: the transfer has to be in the scene from the start, because a resolved
    FLIP scene carries ``method.flip``, which an APIC override would contradict."""
    if interpolator in METHODS:
        transfer = METHODS[interpolator].transfer
        interpolator = METHODS[interpolator].interpolator
    from parmpm.scene.load import scene_from_toml

    h = 1.0 / cells
    axes = "xyz"[:dim]

    def vec(v):
        return "[" + ", ".join(repr(float(c)) for c in v) + "]"

    planes = []
    for k, a in enumerate(axes):
        for lo_face in (True, False):
            lo, hi = [-10.0] * dim, [10.0] * dim
            if lo_face:
                hi[k] = 0.0
            else:
                lo[k] = 1.0
            planes.append(f'{{ min = {vec(lo)}, max = {vec(hi)}, normal = "{a}" }}')
    if faces == "symmetry":  # mirror faces on the body (parmpm.grid.symmetry), exterior layer auto
        origin, n = 0.0, cells
        ps = patch_size or max(6, (cells + 5) // 2)
        boundary = "\n".join(f'{a}_{s} = "symmetry"' for a in axes for s in ("min", "max"))
    elif faces == "slip_regions":  # slip regions holding every node on or beyond the faces
        origin, n = -2 * h, cells + 4
        ps = patch_size or max(4, (n + 1) // 2)
        boundary = f"slip_regions = [{', '.join(planes)}]"
        if interpolator == "bspline":  # refused unless asked for: the study measures their error
            boundary += "\nregions_with_splines = true"
    else:
        raise ValueError(f"faces: expected 'symmetry' or 'slip_regions', got {faces!r}")
    lcr_line = f'lcr = "{lcr}"\n' if interpolator in ("cpdi", "cpdi2") else ""
    text = f"""
name = "manufactured_{dim}d"
dim = {dim}
[grid]
origin = {origin!r}
cell_size = {h!r}
cells = {n}
patch_size = {ps}
[materials.block]
model = "neo_hookean"
density = 1.0
youngs_modulus = 1.0e4
poisson_ratio = 0.3
[[bodies]]
shape = "box"
min = {vec([0.0] * dim)}
max = {vec([1.0] * dim)}
material = "block"
ppc = {ppc}
[manufactured]
amplitude = {amplitude!r}
[method]
interpolator = "{interpolator}"
update = "{update}"
transfer = "{transfer}"
{lcr_line}[boundary]
{boundary}
[time]
end = {0.02 * periods!r}
cfl = {cfl!r}
[output]
every = {0.02 * periods / 20!r}
snapshots = false
figure = false
[metrics]
kind = "manufactured"
"""
    return scene_from_toml(text, f"<manufactured {dim}D, {cells} cells>")


def scene_with(scene, overrides=()):
    """``scene`` (a :class:`parmpm.Scene`, e.g. from :func:`manufactured_scene`) with
    ``section.key=value`` overrides applied on top; the round trip is ``Scene.to_toml`` →
    ``scene_from_toml``."""
    from parmpm.scene.load import scene_from_toml

    return scene_from_toml(scene.to_toml(), scene.source, list(overrides), default_name=scene.name)


class ManufacturedError:
    """Observer (collective) for :func:`manufactured_scene` runs: the RMS over particles of
    ``|x_p − φ(X_p, t)|`` at every output time, from the scene's own metric terms, gathered in
    global-id order (the same rounding on any number of ranks). Lets a study sample the error at
    the output times with ``metrics.every_steps`` set huge: the every-step metrics also count
    connected pieces, which costs more than the time step itself on a 2D manufactured run.
    Use with the overrides of :func:`manufactured_sampling`."""

    def __init__(self):
        self.t: list[float] = []
        self.rms: list[float] = []

    def __call__(self, sim) -> None:
        P = sim.particles
        sums, _ = sim.state.metrics.terms(P.gid, P.x, P.v, P.F, t=sim.t, particles=P)
        g = sim.gather({"e2": np.ascontiguousarray(sums[:, 0])})
        rms = math.sqrt(float(np.sum(g["e2"])) / g["e2"].size) if g is not None else None
        self.t.append(float(sim.t))
        self.rms.append(sim.comm.bcast(rms, root=0))

    @property
    def rms_max(self) -> float:
        return max(self.rms)


def manufactured_sampling(samples: int = 40, periods: float = 1.0) -> list[str]:
    """Overrides for :class:`ManufacturedError`: ``samples`` outputs per period, metrics off."""
    return [f"output.every={0.02 * periods / samples!r}", "metrics.every_steps=1000000000"]


def compact_png(path: Path) -> Path:
    """Re-save a PNG with a 256-colour palette: dense line charts come out ~3x smaller and look
    the same (keeps committed figures under ~300 KB)."""
    from PIL import Image

    with Image.open(path) as im:
        small = im.convert("RGB").quantize(colors=256)
    small.save(path, optimize=True)
    return Path(path)
