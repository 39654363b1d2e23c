"""Fracture and grid alignment: does the tension bar's separation stretch depend on the grid?

Physics. The built-in ``tension_bar`` (2D plane strain, Δx = 0.025 m, CPDI with l_cr = 2Δx): a
neo-Hookean bar (0.8 m x 0.1 m, damage onset/fracture stretches 1.2/1.6) with a four-cell band
in its middle (1.1/1.3) between two heavy stiff grips pulled apart at ε̇ = 0.8 1/s
(``metrics.kind = "tension_bar"``, ``stop_on_separation``). The damage model predicts the bar's
stretch at failure (:mod:`parmpm.exact.tension`: the band peaks and snaps back, λ_fail ≈ 1.11);
the question is when the *numerical* bar comes apart (two connected pieces of material) and how
much that depends on where the particles sit in the background grid. The seed paper's claim:
with plain l_cr scaling the fracture depends on the particles' alignment with the grid, while
coupling damage to a domain freeze makes it depend on the damage parameters instead.

Cases: the scene rotated by each angle (``--angles``, default 0, 15, 30, 45°) about the bar's
centre — every body's centre, velocity and velocity gradient turned with it, the boxes turned by
``angle`` — on a grid whose origin is shifted by each offset (``--offsets N``, default 4: (k/4,
frac(0.37 k)) cell fractions, k = 0..N−1), in two modes:

* ``freeze``: the scene as is — a CPDI domain freezes when its damage reaches 1
  ("damage-triggered freezing"), so the broken band opens by a grid cell soon after failure;
* ``lcr``: the same materials with ``freeze = "never"`` in both damage tables — damage softens
  the material, but the domains only stop growing at the l_cr cap ("plain l_cr scaling"), so the
  bar separates only once the capped domains leave a gap the grid sees.

Each case runs until separation or until the bar's stretch reaches ``--max-stretch`` (default
2.2; ``time.end = (max_stretch − 1)/ε̇``; the grid is large enough for the grips to get there at
any angle) at the scene's CFL number 0.4; a case that blows up (non-finite velocity or stress)
is run once more at 0.2 and flagged (``status``, ``cfl``, ``error``), and reported as
``unstable`` if that fails too. Expected: every freeze case separates at a stretch in
[λ_fail, λ_fail + 2Δx/L_bar] (within two cells of opening of the prediction), the crack inside
the band, with a spread over angles and offsets of a fraction of 2Δx/L_bar; the lcr cases
separate later and with a larger spread (or not at all by ``--max-stretch``: reported as
``separated = False``).

Found (full run: 4 angles x 4 offsets x 2 modes, one rank, 27 s; predicted λ_fail = 1.1137,
two cells of opening 2Δx/L_bar = 0.0625; statistics over the separated cases):

    mode    cases  separated  mean    min     max     spread  std     excess  crack in band
    freeze  16     16         1.1323  1.1252  1.1436  0.0184  0.0053  0.0186  100 %
    lcr     16     16         1.2682  1.1360  1.5358  0.3998  0.0851  0.1545  100 %

* freeze: every case separates 0.011–0.030 past the prediction (well inside the two-cell window),
  in the band, 0.004–0.024 after the first fully damaged particle (failure at 1.118–1.122, i.e.
  0.004–0.008 past the predicted peak). Rotation changes nothing beyond the offsets' scatter.
* lcr: the same damage and failure stretch (identical until the first domain would have frozen),
  but separation 0.008–0.41 later than the freeze twin and with a 22x larger spread (std 16x):
  from 1.136 (0°, x-offsets ¼ and ¾ cell: there the capped domains happen to leave a cell-wide
  gap almost at once) to 1.536 (0°, offset (0, 0)). None separates earlier than its freeze twin.
  No case needed the CFL retry. (Before the damage model kept a broken particle's compressive
  pressure by ``p_v`` rather than the mean stress, two lcr cases blew up after failure: broken
  particles sheared flat to J → 0; see :mod:`parmpm.materials.damage`.)

Outputs: ``fracture_alignment.csv`` (one row per case: mode, angle, offset, status, CFL number,
whether and at what stretch the bar separated, the failure stretch, peak stress, crack position,
steps, wall time, the error of a blown-up run) and ``fracture_alignment_summary.csv`` (per mode:
cases, separated cases, mean/min/max/spread/std (population) of the separation stretch over the
separated cases, the mean excess over the predicted failure stretch, the fraction of *all* cases
whose crack lies within the weak band, retried and unstable cases) in ``--out`` (default
``run_scripts/out/fracture_alignment``); ``fracture_alignment.png`` in ``--out`` too (``make
figures`` passes ``--figures docs/figures``): separation stretch against angle, one panel per mode
on one stretch scale, a marker per offset, the prediction and the freeze mode's two-cell allowance
drawn in.

Runtime, one core: full (32 runs) ~30 s — freeze cases ~0.2 s each, lcr 0.2–3 s (the later
they separate the longer, and their time step shrinks after failure); ``--quick`` (angles 0 and 30°, offsets (0, 0) and
(0.5, 0.37), max stretch 1.6: 8 runs) ~8 s. Results are identical on any number of ranks (only
``wall_s`` differs)::

    python run_scripts/studies/fracture_alignment.py                    # full study, figure beside the CSV
    python run_scripts/studies/fracture_alignment.py --quick            # the smoke test's mode
    mpirun -n 2 python run_scripts/studies/fracture_alignment.py --quick
    python run_scripts/studies/fracture_alignment.py --angles 0,10,20 --offsets 2 --modes freeze
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from study import (compact_png, figure, folders, is_root, main_guard, parser, run_case, save,
                   scratch_folder, world, write_csv, wrote)

MODES = ("freeze", "lcr")
MODE_OVERRIDES = {"freeze": [],
                  "lcr": ["materials.bar.damage.freeze=never", "materials.band.damage.freeze=never"]}
TITLES = {"freeze": "freeze: damage-triggered domain freezing",
          "lcr": 'lcr: plain l_cr scaling (freeze = "never")'}
COLOURS = {"freeze": "tab:blue", "lcr": "tab:red"}
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
EPS_DOT = 0.8        # 1/s, the scene's strain rate
DX = 0.025           # m, the scene's cell
HALF_HEIGHT = 0.05   # m, half the bar's (and the grips') height
HALF_BAR = 0.4       # m, half the bar's length between the grips
GRIP = 0.1           # m, a grip's length along the bar
BAND = 0.05          # m, half the band's width (four cells)
DEFAULT_ANGLES = "0,15,30,45"
QUICK_ANGLES = "0,30"
QUICK_MAX_STRETCH = 1.6
ROOM = 8             # cells of grid around the assembly (cheap: only occupied patches exist)
CFLS = (0.4, 0.2)    # the scene's CFL number, and the one retry of a case that blows up

# (centre along the bar, half-length along it, material, affine velocity field inside it);
# every centre moves at ε̇·c, the grips rigidly, the bar segments with the gradient ε̇ e⊗e
_BODIES = (
    (-(HALF_BAR + GRIP / 2), GRIP / 2, "grip", False),
    (-(HALF_BAR + BAND) / 2, (HALF_BAR - BAND) / 2, "bar", True),
    (0.0, BAND, "band", True),
    ((HALF_BAR + BAND) / 2, (HALF_BAR - BAND) / 2, "bar", True),
    (HALF_BAR + GRIP / 2, GRIP / 2, "grip", False),
)

_MATERIALS = """
[materials.bar]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
damage = { onset = 1.2, fracture = 1.6 }

[materials.band]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
damage = { onset = 1.1, fracture = 1.3 }

[materials.grip]
model = "neo_hookean"
density = 1.0e9
youngs_modulus = 1.0e8
poisson_ratio = 0.3
"""


def default_offsets(n: int) -> list[tuple[float, float]]:
    """``n`` grid-origin offsets in cell fractions: (k/n, frac(0.37 k)), k = 0..n−1."""
    return [(k / n, (0.37 * k) % 1.0) for k in range(n)]


def _vec(v) -> str:
    return "[" + ", ".join(repr(float(c)) for c in v) + "]"


def _rows(m) -> str:
    return "[" + ", ".join(_vec(r) for r in m) + "]"


def tension_scene(angle_deg: float, offset=(0.0, 0.0), cells_per_m: float = 40.0,
                  max_stretch: float = 2.2, eps_dot: float = EPS_DOT) -> str:
    """TOML text of the tension bar turned by ``angle_deg`` (counter-clockwise) about the bar's
    centre (0, 0): each body's centre c → R·c, its box R·c ± its unturned half sizes with
    ``angle = angle_deg``, its velocity ε̇·R·(c_x, 0) and velocity gradient R·L·Rᵀ with
    L = diag(ε̇, 0). Cell size ``1/cells_per_m``; the grid covers the whole assembly at the bar
    stretch ``max_stretch`` (half-length 0.4·λ + grip 0.1, half-height 0.05, turned) plus ``ROOM``
    cells on every side, its origin shifted by ``offset`` (cell fractions) from a multiple of the
    cell size (offset (0, 0): the unturned bodies' edges lie on cell faces, as in the built-in
    scene). ``time.end = (max_stretch − 1)/ε̇``; metrics stop the run at separation."""
    h = 1.0 / cells_per_m
    a = math.radians(angle_deg)
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    L = np.array([[eps_dot, 0.0], [0.0, 0.0]])
    L_turned = R @ L @ R.T
    # reach of the assembly at max_stretch, turned: a box 2A x 2B about the origin
    A, B = HALF_BAR * max_stretch + GRIP, HALF_HEIGHT
    reach = np.array([abs(R[0, 0]) * A + abs(R[0, 1]) * B, abs(R[1, 0]) * A + abs(R[1, 1]) * B])
    # ROOM cells of room (broken particles of the band flail sideways) + 1 for the offset
    n_half = np.ceil(reach / h - 1e-9).astype(int) + ROOM + 1
    origin = -n_half * h + np.asarray(offset, float) * h
    cells = 2 * n_half
    bodies = []
    for cx, half_x, material, affine in _BODIES:
        c = R @ np.array([cx, 0.0])
        half = np.array([half_x, HALF_HEIGHT])
        v = R @ (L @ np.array([cx, 0.0]))
        lines = ["[[bodies]]", f"min = {_vec(c - half)}", f"max = {_vec(c + half)}",
                 f"angle = {float(angle_deg)!r}", f'material = "{material}"',
                 f"velocity = {_vec(v)}"]
        if affine:
            lines.append(f"velocity_gradient = {_rows(L_turned)}")
        bodies.append("\n".join(lines))
    end = (max_stretch - 1.0) / eps_dot
    return f"""# the built-in tension_bar turned by {angle_deg!r} degrees, grid offset {tuple(offset)!r} cells
description = "Tension bar turned by {float(angle_deg):g} deg, grid origin offset {offset[0]:.3g}, {offset[1]:.3g} cells"
dim = 2

[grid]
origin = {_vec(origin)}
cell_size = {h!r}
cells = [{cells[0]}, {cells[1]}]
{_MATERIALS}
{chr(10).join(chr(10) + b for b in bodies)}

[method]
interpolator = "cpdi"

[time]
end = {end!r}
cfl = 0.4

[output]
every = {end / 10!r}
snapshots = false
figure = false

[metrics]
kind = "tension_bar"
every_steps = 5
stop_on_separation = true
"""


@dataclass(frozen=True)
class Case:
    mode: str
    angle: float
    offset: tuple[float, float]

    @property
    def id(self) -> str:
        return f"{self.mode}_a{self.angle:g}_o{self.offset[0]:.3g}_{self.offset[1]:.3g}"


def _num(v) -> float:
    return math.nan if v is None else float(v)


def run_one(case: Case, scene_path: Path, comm) -> dict:
    """One case at the scene's CFL number; a run that blows up (non-finite velocity or stress:
    seen with ``lcr`` after failure) is run again once at half of it, and reported as such."""
    from parmpm.core.errors import SimulationError

    wall, error = 0.0, ""
    for cfl in CFLS:
        t0 = time.perf_counter()
        try:
            summary, w = run_case(scene_path, MODE_OVERRIDES[case.mode] + [f"time.cfl={cfl!r}"],
                                  comm=comm)
        except SimulationError as exc:  # raised on every rank alike (a collective check)
            wall += time.perf_counter() - t0
            error = error or str(exc)
            continue
        wall += w
        break
    else:
        return {**_blank_row(case), "status": "unstable", "cfl": math.nan, "wall_s": wall,
                "error": error}
    m = summary["metrics"]
    status = "separated" if m["separated"] else "not separated"
    return {
        "mode": case.mode, "angle": float(case.angle),
        "offset_x": float(case.offset[0]), "offset_y": float(case.offset[1]),
        "status": status if cfl == CFLS[0] else f"{status} (cfl {cfl:g} retry)",
        "cfl": float(cfl),
        "separated": bool(m["separated"]),
        "stretch_at_separation": _num(m["stretch_at_separation"]),
        "stretch_at_failure": _num(m["stretch_at_failure"]),
        "predicted_failure_stretch": _num(m["predicted_failure_stretch"]),
        "peak_stress": _num(m["peak_stress"]),
        "predicted_peak_stress": _num(m["predicted_peak_stress"]),
        "stretch_at_peak_stress": _num(m["stretch_at_peak_stress"]),
        "crack_position": _num(m["crack_position"]),
        "weak_segment_halfwidth": _num(m["weak_segment_halfwidth"]),
        "separation_time": _num(m["separation_time"]),
        "max_stretch": _num(m["max_stretch"]),
        "steps": int(summary["steps"]),
        "wall_s": wall,
        "error": error,
    }


def _blank_row(case: Case) -> dict:
    row = {"mode": case.mode, "angle": float(case.angle), "offset_x": float(case.offset[0]),
           "offset_y": float(case.offset[1]), "status": "", "cfl": math.nan, "separated": False}
    for key in ("stretch_at_separation", "stretch_at_failure", "predicted_failure_stretch",
                "peak_stress", "predicted_peak_stress", "stretch_at_peak_stress", "crack_position",
                "weak_segment_halfwidth", "separation_time", "max_stretch"):
        row[key] = math.nan
    row["steps"] = 0
    return row


def crack_in_band(r: dict) -> bool:
    return (r["separated"] and math.isfinite(r["crack_position"])
            and abs(r["crack_position"]) <= r["weak_segment_halfwidth"] * (1 + 1e-9) + 1e-12)


def predicted(rows: list[dict]) -> float:
    """The predicted failure stretch (the same bar in every case; NaN only if none ran)."""
    vals = [r["predicted_failure_stretch"] for r in rows if math.isfinite(r["predicted_failure_stretch"])]
    return vals[0] if vals else math.nan


def summarise(rows: list[dict], modes) -> list[dict]:
    out = []
    for mode in modes:
        mine = [r for r in rows if r["mode"] == mode]
        if not mine:
            continue
        sep = np.array([r["stretch_at_separation"] for r in mine if r["separated"]])
        excess = np.array([r["stretch_at_separation"] - r["predicted_failure_stretch"]
                           for r in mine if r["separated"]])
        any_sep = sep.size > 0
        out.append({
            "mode": mode, "cases": len(mine), "separated": int(sep.size),
            "mean": float(sep.mean()) if any_sep else math.nan,
            "min": float(sep.min()) if any_sep else math.nan,
            "max": float(sep.max()) if any_sep else math.nan,
            "spread": float(sep.max() - sep.min()) if any_sep else math.nan,
            "std": float(sep.std()) if any_sep else math.nan,
            "mean_excess": float(excess.mean()) if any_sep else math.nan,
            "crack_in_band_fraction": sum(crack_in_band(r) for r in mine) / len(mine),
            "retried": sum("retry" in r["status"] for r in mine),
            "unstable": sum(r["status"] == "unstable" for r in mine),
            "predicted_failure_stretch": predicted(mine),
            "max_stretch_reached": float(np.nanmax([r["max_stretch"] for r in mine])),
        })
    return out


def table(summary: list[dict]) -> str:
    head = (f"{'mode':7s} {'cases':>5s} {'sep':>4s} {'mean':>7s} {'min':>7s} {'max':>7s} "
            f"{'spread':>7s} {'std':>7s} {'excess':>7s} {'in band':>7s} {'retried':>7s} "
            f"{'unstable':>8s}")
    lines = [head]
    for s in summary:
        lines.append(f"{s['mode']:7s} {s['cases']:5d} {s['separated']:4d} {s['mean']:7.4f} "
                     f"{s['min']:7.4f} {s['max']:7.4f} {s['spread']:7.4f} {s['std']:7.4f} "
                     f"{s['mean_excess']:7.4f} {s['crack_in_band_fraction']:7.2f} "
                     f"{s['retried']:7d} {s['unstable']:8d}")
    return "\n".join(lines)


def chart(rows: list[dict], summary: list[dict], offsets, angles, max_stretch: float,
          path: Path) -> Path:
    from matplotlib.lines import Line2D

    modes = [s["mode"] for s in summary]
    fig, axes = figure(1, len(modes), size=(5.4 * len(modes), 4.4))
    pred = predicted(rows)
    allowance = 2 * DX / (2 * HALF_BAR)
    width = (max(angles) - min(angles)) if len(angles) > 1 else 30.0
    jitter = 0.025 * width
    all_ys = []
    for ax, s in zip(axes[0], summary):
        mode = s["mode"]
        mine = [r for r in rows if r["mode"] == mode]
        ax.axhline(pred, color="k", lw=1.0, ls="--", zorder=1)
        ax.axhspan(pred, pred + allowance, color="0.85", zorder=0)
        ys = [pred, pred + allowance]
        for k, off in enumerate(offsets):
            pts = [r for r in mine if (r["offset_x"], r["offset_y"]) == (float(off[0]), float(off[1]))]
            dx = (k - (len(offsets) - 1) / 2) * jitter
            for r in pts:
                x = r["angle"] + dx
                if r["status"] == "unstable":
                    continue
                if r["separated"]:
                    ax.plot(x, r["stretch_at_separation"], MARKERS[k % len(MARKERS)],
                            color=COLOURS[mode], ms=6, mfc="white" if k % 2 else COLOURS[mode],
                            mew=1.2, zorder=3)
                    ys.append(r["stretch_at_separation"])
                    if "retry" in r["status"]:
                        ax.annotate(f"cfl {r['cfl']:g}", (x, r["stretch_at_separation"]),
                                    xytext=(5, -3), textcoords="offset points", fontsize=6)
                else:  # ran to max stretch without separating
                    ax.plot(x, r["max_stretch"], "^", color="0.4", ms=7, mfc="none", zorder=3)
                    ys.append(r["max_stretch"])
                if math.isfinite(r["stretch_at_failure"]):
                    ax.plot(x, r["stretch_at_failure"], "_", color="0.3", ms=7, zorder=2)
        all_ys += ys
        ax.set_xticks(list(angles))
        ax.set_xlim(min(angles) - 0.1 * width, max(angles) + 0.1 * width)
        ax.set_xlabel("bar angle to the grid (degrees)", fontsize=8)
        ax.set_ylabel("bar stretch at separation", fontsize=8)
        ax.set_title(TITLES[mode], fontsize=9)
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.tick_params(labelsize=7)
        notes = "".join(f"; {s[k]} {k}" for k in ("retried", "unstable") if s[k])
        if s["retried"]:
            notes += f" (at cfl {CFLS[1]:g})"
        txt = (f"{s['separated']}/{s['cases']} separated{notes}\nspread {s['spread']:.3g}, "
               f"std {s['std']:.2g}\nmean excess over prediction {s['mean_excess']:.3g}; "
               f"crack in band {s['crack_in_band_fraction']:.0%}")
        ax.text(0.02, 0.97, txt, transform=ax.transAxes, va="top", fontsize=7,
                bbox=dict(facecolor="white", edgecolor="0.7", alpha=0.9))
    lo, hi = min(all_ys), max(all_ys)  # one scale for both modes: spreads compare by eye
    pad = 0.06 * max(hi - lo, 0.02)
    for ax in axes[0]:
        ax.set_ylim(lo - pad, hi + 6.0 * pad)  # room above the points for the note and legend
    handles = [Line2D([], [], color="k", ls="--", label=f"predicted failure stretch {pred:.4f}"),
               Line2D([], [], color="0.85", lw=6, label="prediction + 2Δx/L (two cells of opening)"),
               Line2D([], [], color="0.3", marker="_", ls="", ms=8, label="first fully damaged particle")]
    handles += [Line2D([], [], color="0.2", marker=MARKERS[k % len(MARKERS)], ls="",
                       mfc="white" if k % 2 else "0.2",
                       label=f"grid offset ({o[0]:.2f}, {o[1]:.2f}) Δx") for k, o in enumerate(offsets)]
    if any(not r["separated"] for r in rows):
        handles.append(Line2D([], [], color="0.4", marker="^", ls="", mfc="none",
                              label=f"not separated by stretch {max_stretch:g}"))
    # the freeze panel has room above its points (one stretch scale for both)
    axes[0][0].legend(handles=handles, fontsize=6.5, loc="upper right", bbox_to_anchor=(1.0, 0.8),
                      framealpha=0.9)
    fig.suptitle("Tension bar (Δx = 0.025 m, CPDI, l_cr = 2Δx): separation stretch over grid "
                 "offsets and rotations", fontsize=10)
    return compact_png(save(fig, path))


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x.strip()]


def main() -> int:
    ap = parser(__doc__)
    ap.add_argument("--angles", default=None,
                    help=f"comma-separated bar angles in degrees (default {DEFAULT_ANGLES}; "
                         f"--quick: {QUICK_ANGLES})")
    ap.add_argument("--offsets", type=int, default=None,
                    help="number of grid-origin offsets (k/N, frac(0.37k)) (default 4; --quick: 2)")
    ap.add_argument("--max-stretch", type=float, default=None,
                    help=f"stop a case at this bar stretch (default 2.2; --quick: {QUICK_MAX_STRETCH})")
    ap.add_argument("--modes", default=",".join(MODES), help="comma-separated subset of freeze, lcr")
    args = ap.parse_args()
    angles = _floats(args.angles or (QUICK_ANGLES if args.quick else DEFAULT_ANGLES))
    n_off = args.offsets or (2 if args.quick else 4)
    max_stretch = args.max_stretch or (QUICK_MAX_STRETCH if args.quick else 2.2)
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    if not modes or any(m not in MODES for m in modes):
        raise SystemExit(f"--modes: choose from {', '.join(MODES)}")
    if not angles or n_off < 1 or max_stretch <= 1.0:
        raise SystemExit("need at least one angle, one offset and --max-stretch > 1")
    offsets = default_offsets(n_off)
    comm = world()
    root = is_root(comm)
    out, figs = folders(args, "fracture_alignment")
    rows = []
    t0 = time.perf_counter()
    with scratch_folder(comm, "parmpm-fracture-") as scratch:
        for angle in angles:
            for k, off in enumerate(offsets):
                # run_case re-reads the scene from a file: Scene round trips lose freeze = "never"
                path = scratch / f"tension_a{angle:g}_o{k}.toml"
                if root:
                    path.write_text(tension_scene(angle, off, max_stretch=max_stretch),
                                    encoding="utf-8")
                comm.Barrier()
                for mode in modes:
                    case = Case(mode, angle, off)
                    row = run_one(case, path, comm)
                    rows.append(row)
                    if root:
                        sep = (f"separated at stretch {row['stretch_at_separation']:.4f} "
                               f"(crack at {row['crack_position']:+.4f} m)" if row["separated"]
                               else f"not separated by stretch {row['max_stretch']:.3f}")
                        if row["status"] == "unstable":
                            sep = f"unstable: {row['error']}"
                        elif "retry" in row["status"]:
                            sep += f" [cfl {row['cfl']:g} retry: {row['error']}]"
                        print(f"{case.id:26s} {sep}; failure at {row['stretch_at_failure']:.4f}; "
                              f"{row['steps']} steps, {row['wall_s']:.1f} s", flush=True)
    summary = summarise(rows, modes)
    write_csv(out / "fracture_alignment.csv", rows, comm)
    write_csv(out / "fracture_alignment_summary.csv", summary, comm)
    if root:
        print(f"\npredicted failure stretch {predicted(rows):.4f}; "
              f"two cells of opening: +{2 * DX / (2 * HALF_BAR):.4f}; separation stretch over "
              "the separated cases:")
        print(table(summary))
        path = chart(rows, summary, offsets, angles, max_stretch, figs / "fracture_alignment.png")
        print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s on {comm.Get_size()} rank(s)")
        print(f"wrote {out / 'fracture_alignment.csv'} and fracture_alignment_summary.csv")
        print(wrote(path))
    return 0


if __name__ == "__main__":
    main_guard(main)
