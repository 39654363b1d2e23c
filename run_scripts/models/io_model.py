"""Checkpoint I/O added to the step-time cost model (``cost_model.py``): write and restart time,
and the checkpoint interval that keeps checkpoints below 1 % of run time.

Pure arithmetic (no MPI, no parmpm, no files): ``run_scripts/benchmarks/io_scaling.py`` measures the
per-writer rates on this machine and calls :func:`io_rows` for the 3D cpdi cube.

**Checkpoint write on P ranks** (format version 4, ``docs/checkpoints.md``)::

    T_w(N, P) = S·N / min(P_w·b_w, B_fs)        data: P_w writers, each at b_w, capped by the file system
              + (r − 1)·S·(N/P) / β              a group's lead receives its r − 1 members' rows
              + t_0 + P_w·t_md                   fixed cost, and the part files' creates at the metadata server
              + α_r·⌈log2 P⌉                     the collectives that agree on sizes and digests

* ``S`` — bytes per particle in a checkpoint (:func:`row_bytes`): gid, mat (int64); x, v, x0, lh0
  (d doubles each); mass, vol0, damage; F, stress, r0, rf (d² each): ``8·(5 + 4d + 4d²)`` — 232 B
  in 2D (measured: 928.1 MB for 4·10⁶ particles, the HDF5 headers and digests add 0.01 %), 424 B
  in 3D.
* ``P_w`` — writers (:func:`writers`): ``ranks_per_file = "auto"`` gives one part per rank up to
  256 ranks, then groups of ``r = ⌈P/256⌉`` consecutive ranks, ``⌈P/r⌉`` ≤ 256 files.
* ``b_w`` — one writer's rate, *measured* here as the 1-rank checkpoint write (HDF5, SHA-256 of
  every segment, fsync); ``B_fs`` — the file system's aggregate bandwidth, an *assumption*
  (100 GB/s for a Lustre-class parallel file system; 10 GB/s for a small one).
* ``β`` — the MPI bandwidth between a lead and its members (same node: the measured ping-pong).
* ``t_0`` — the fixed cost of a checkpoint (rank 0's top-level file, its virtual datasets and
  part table, fsyncs, renames), measured as the write time of a tiny checkpoint; ``t_md`` — one
  metadata operation at the file system's metadata server, *assumed* 0.1 ms (10⁴ creates or
  opens per second, serialised).

**Restart** reads every rank's own patches' rows from the parts (``P_r = P`` readers)::

    T_r(N, P) = S·N / min(P·b_r, B_fs) + t_0r + 2P·t_md

``b_r`` is the measured 1-rank restart rate (its set-up included: opening, dealing the patches
out, checking the digests, building the stepper) and ``2P·t_md`` every rank's opens of the
top-level file and its part.

**The old strategy** (format ≤ 3): rank 0 gathered every row and wrote alone,
``T_w = S·N/min(b_w, B_fs) + S·N·(P − 1)/(P·β) + t_0``, and at restart every rank read the whole scene's
positions, reference positions and masses (``8·(2d + 1)`` B per particle) before its own rows:
``T_r = max((8(2d+1)·N + S·N/P)/b_r, (P·8(2d+1)·N + S·N)/B_fs) + t_0r``.

**Checkpoint interval.** A checkpoint every ``k`` steps of ``T_step`` costs
``T_w/(k·T_step + T_w)`` of the run; below a share ``f`` (1 %) when
``k ≥ (1 − f)/f · T_w/T_step`` — in wall time ``k·T_step ≥ 99·T_w``, whatever the step.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

#: checkpoint.ranks_per_file = "auto": at most this many part files (parmpm.io.checkpoint_parts)
MAX_PARTS = 256
#: the share of run time checkpoints may take
SHARE = 0.01


@dataclass(frozen=True)
class Storage:
    """I/O constants: per-writer and per-reader rates b_w, b_r (bytes/s), the file system's
    aggregate B_fs (bytes/s), fixed costs t_0, t_0r (s), one metadata operation t_md (s), the
    intra-node MPI bandwidth β (bytes/s) and Allreduce stage α_r (s)."""

    b_w: float
    b_r: float
    B_fs: float
    t_0: float
    t_0r: float
    t_md: float
    beta: float
    alpha_r: float

    def as_dict(self) -> dict:
        return asdict(self)


def row_bytes(dim: int) -> int:
    """``S``: bytes per particle in a checkpoint, ``8·(5 + 4d + 4d²)`` (232 in 2D, 424 in 3D)."""
    return 8 * (2 + 4 * dim + 3 + 4 * dim * dim)


def position_bytes(dim: int) -> int:
    """Bytes per particle every rank read at a version ≤ 3 restart: x, x0, mass."""
    return 8 * (2 * dim + 1)


def ranks_per_file(P: int, max_parts: int = MAX_PARTS) -> int:
    """``r = ⌈P/256⌉``: the ``"auto"`` group size."""
    return max(1, -(-P // max_parts))


def writers(P: int, max_parts: int = MAX_PARTS) -> int:
    """``P_w = ⌈P/r⌉``: part files (and writers) under ``"auto"``."""
    return -(-P // ranks_per_file(P, max_parts))


def write_time(N: float, P: int, dim: int, st: Storage) -> dict:
    """The terms of ``T_w`` (seconds) for the parts layout, and their total."""
    S, r, Pw = row_bytes(dim), ranks_per_file(P), writers(P)
    terms = {"data": S * N / min(Pw * st.b_w, st.B_fs),
             "gather": (r - 1) * S * N / P / st.beta,
             "fixed": st.t_0 + Pw * st.t_md,
             "collective": st.alpha_r * math.ceil(math.log2(P)) if P > 1 else 0.0}
    return dict(terms, total=sum(terms.values()), writers=Pw, ranks_per_file=r)


def read_time(N: float, P: int, dim: int, st: Storage) -> dict:
    """The terms of ``T_r`` (seconds): each rank reads its own rows from the parts."""
    terms = {"data": row_bytes(dim) * N / min(P * st.b_r, st.B_fs),
             "fixed": st.t_0r + 2 * P * st.t_md}
    return dict(terms, total=sum(terms.values()))


def old_write_time(N: float, P: int, dim: int, st: Storage) -> float:
    """Format ≤ 3: rank 0 gathers every row and writes alone."""
    S = row_bytes(dim)
    return S * N / min(st.b_w, st.B_fs) + S * N * (P - 1) / P / st.beta + st.t_0


def old_read_time(N: float, P: int, dim: int, st: Storage) -> float:
    """Format ≤ 3: every rank reads the whole scene's positions, then its own rows."""
    S, X = row_bytes(dim), position_bytes(dim)
    return max((X * N + S * N / P) / st.b_r, (P * X * N + S * N) / st.B_fs) + st.t_0r


def interval_steps(T_ck: float, T_step: float, share: float = SHARE) -> int:
    """The fewest steps between checkpoints for which they cost at most ``share`` of run time:
    ``⌈(1 − f)/f · T_ck/T_step⌉``."""
    return max(1, math.ceil((1.0 - share) / share * T_ck / T_step))


def io_rows(particles, ranks, step_seconds: dict, storages: dict, dim: int = 3) -> list[dict]:
    """One row per (file system, N, P): write and restart time (parts and old), their terms, and
    the shortest checkpoint interval (steps, wall minutes) under 1 % of run time.
    ``step_seconds[(N, P)]``: the cost model's T_step (NaN: more ranks than patches)."""
    rows = []
    for label, st in storages.items():
        for N in particles:
            for P in ranks:
                w, r = write_time(N, P, dim, st), read_time(N, P, dim, st)
                old_w, old_r = old_write_time(N, P, dim, st), old_read_time(N, P, dim, st)
                T = step_seconds.get((N, P), math.nan)
                ok = math.isfinite(T)
                k = interval_steps(w["total"], T) if ok else math.nan
                k_old = interval_steps(old_w, T) if ok else math.nan
                rows.append({
                    "file_system": label, "B_fs": st.B_fs, "dim": dim, "particles": float(N),
                    "ranks": int(P), "writers": w["writers"], "ranks_per_file": w["ranks_per_file"],
                    "checkpoint_bytes": row_bytes(dim) * N, "step_seconds": T,
                    "write_seconds": w["total"], "write_data": w["data"], "write_gather": w["gather"],
                    "write_fixed": w["fixed"], "restart_seconds": r["total"],
                    "old_write_seconds": old_w, "old_restart_seconds": old_r,
                    "interval_steps": k, "interval_minutes": k * T / 60 if ok else math.nan,
                    "old_interval_steps": k_old,
                    "old_interval_minutes": k_old * T / 60 if ok else math.nan})
    return rows


def io_table(rows: list[dict], label: str) -> str:
    """The table of docs/results/memory-io.md for one file system: checkpoint time and the 1 % interval."""
    mine = [r for r in rows if r["file_system"] == label]
    sizes = sorted({r["particles"] for r in mine})
    ranks = sorted({r["ranks"] for r in mine})
    head = "| particles | " + " | ".join(f"{P:,} ranks" for P in ranks) + " |"
    lines = [head, "|---" * (len(ranks) + 1) + "|"]
    for N in sizes:
        cells = []
        for P in ranks:
            r = next(x for x in mine if x["particles"] == N and x["ranks"] == P)
            if not math.isfinite(r["step_seconds"]):
                cells.append(f"{r['write_seconds']:.3g} s; — (more ranks than patches)")
                continue
            cells.append(f"{r['write_seconds']:.3g} s (old {_dur(r['old_write_seconds'])}); "
                         f"every {r['interval_steps']:,} steps = {_dur(60 * r['interval_minutes'])}")
        lines.append(f"| 10^{round(math.log10(N))} ({_size(r['checkpoint_bytes'])}) | "
                     + " | ".join(cells) + " |")
    return "\n".join(lines)


def _dur(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 7200:
        return f"{seconds / 60:.3g} min"
    return f"{seconds / 3600:.3g} h"


def _size(nbytes: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes:.0f} B"
