"""``parmpm bench``'s results: the result record built from a run summary, its table, the sweep's
one-line-per-case summary and CSV.

Split from :mod:`parmpm.cli.bench` (which runs the cases) along the seam between measuring and
reporting; pure Python and numpy, no solver imports.
"""
from __future__ import annotations

from pathlib import Path

from parmpm.core.errors import ParmpmError

HALO_PHASES = ("accumulate", "fill")  # the two halo exchanges of a step, reported together as "halo"


def _ratio(work: dict | None) -> float | None:
    """``max / mean`` of the ranks' computing time per step (1: perfectly even)."""
    return work["max"] / work["mean"] if work and work["mean"] > 0 else None


def summarise(summary: dict, setup_seconds: float, migrated: int, peak_rss_mb: float) -> dict:
    """The bench result from a run summary: the timed steps exclude the first step."""
    rate = summary["particle_steps_per_second"]
    phases = summary["phase_seconds_per_step"]
    if not rate or not phases:
        raise ParmpmError("bench: no timed steps (the run stopped after its first step)")
    n, timed = summary["particles"], summary["steps"] - 1
    per_step = n / rate
    share = {k: v / per_step for k, v in phases.items()}
    share["halo"] = sum(share[k] for k in HALO_PHASES)
    return {
        "ranks": summary["ranks"], "dim": summary["dim"], "method": summary["method"],
        "lcr": summary["lcr"], "update": summary["update"],
        "transfer": summary.get("transfer", "flip"),
        "particles": n, "steps": summary["steps"], "timed_steps": timed,
        "seconds_per_step": per_step,
        "particle_steps_per_second": rate,
        "ns_per_particle_step": 1e9 * per_step * summary["ranks"] / n,
        "phase_seconds_per_step": dict(phases, halo=sum(phases[k] for k in HALO_PHASES)),
        # per-rank computing time (p2g, grid, g2p, sort): the slowest rank sets the step, the
        # others wait for it in the halo exchange and the Δt reduction
        "rank_work_seconds_per_step": summary.get("rank_work_seconds_per_step"),
        "work_imbalance": _ratio(summary.get("rank_work_seconds_per_step")),
        "phase_share": share,
        "halo_share": share["halo"], "migrate_share": share["migrate"],
        "particles_migrated": migrated,
        "setup_seconds": setup_seconds,
        "first_step_seconds": max(0.0, summary["wall_seconds"] - timed * per_step),
        "wall_seconds": summary["wall_seconds"],
        "peak_rss_mb_per_rank": peak_rss_mb,
        "grid": summary["grid"],
        "decomposition": summary["decomposition"],
    }


def format_result(r: dict) -> str:
    """The human-readable table of a bench result."""
    dec = r["decomposition"]
    stress = r.get("stress_in_g2p_seconds_per_step")
    lines = [
        f"parmpm bench: {r['dim']}D {r['method']} ({r['update']}), {r['particles']:,} particles, "
        f"{r['ranks']} rank(s), {r['timed_steps']} timed steps"
        + (f", fixed Δt = {r['fixed_dt']:.3g} s" if r.get("fixed_dt") else ""),
        f"  grid {' x '.join(map(str, r['grid']['cells']))} cells, patches "
        f"{' x '.join(map(str, r['grid']['patch_size']))}: {dec['patches']} occupied of "
        f"{dec['patches_dense']}, ghost {dec['ghost']}",
        f"  time per step        {r['seconds_per_step']:.4g} s",
        f"  particle-steps / s   {r['particle_steps_per_second']:.4g} "
        f"({r['ns_per_particle_step']:.1f} ns per particle-step and core)",
        f"  JIT warm-up          {r.get('jit_warmup_seconds', float('nan')):.3g} s "
        f"(set-up {r['setup_seconds']:.3g} s, first step {r['first_step_seconds']:.3g} s)",
        f"  memory               {r.get('bytes_per_particle', float('nan')):.0f} B per particle "
        f"(peak {r['peak_rss_mb_per_rank']:.0f} MiB per rank, interpreter included)",
        f"  imbalance            {dec['imbalance']:.3f} (particles per rank {dec['particles_per_rank']})",
        *([f"  work per rank        {1e3 * r['rank_work_seconds_per_step']['min']:.4g} / "
           f"{1e3 * r['rank_work_seconds_per_step']['mean']:.4g} / "
           f"{1e3 * r['rank_work_seconds_per_step']['max']:.4g} ms/step (min / mean / max; "
           f"max/mean {r['work_imbalance']:.3f})"] if r.get("work_imbalance") else []),
        f"  halo traffic         {dec['halo_bytes_per_step'] / 2**20:.3g} MiB/step; "
        f"migrated {r['particles_migrated']} particles; rebalances {dec['rebalances']}",
        "  phase         s/step      share",
    ]
    per_step = r["seconds_per_step"]
    for name, sec in r["phase_seconds_per_step"].items():
        label = "halo (a+f)" if name == "halo" else name
        lines.append(f"  {label:<12} {sec:10.4g}  {100 * r['phase_share'][name]:6.1f} %")
        if name == "g2p" and stress is not None:
            lines.append(f"   (stress)    {stress:10.4g}  {100 * stress / per_step:6.1f} %  "
                         "inside g2p, timed on its own")
    return "\n".join(lines)


SUMMARY_COLUMNS = ("dim", "method", "update", "ranks", "particles", "ppc", "steps",
                   "seconds_per_step", "particle_steps_per_second", "ns_per_particle_step",
                   "bytes_per_particle", "jit_warmup_seconds", "setup_seconds",
                   "stress_in_g2p_seconds_per_step", "halo_bytes_per_step", "work_imbalance")


def _row(r: dict) -> dict:
    row = {k: r.get(k) for k in SUMMARY_COLUMNS}
    row["halo_bytes_per_step"] = r["decomposition"]["halo_bytes_per_step"]
    for k, v in r["phase_seconds_per_step"].items():
        row[f"phase_{k}"] = v
    return row


def write_csv(path: Path, results: list[dict]) -> None:
    """One row per case: the summary columns and every phase's seconds per step."""
    import csv

    rows = [_row(r) for r in results]
    names = list(dict.fromkeys(k for row in rows for k in row))
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=names)
        writer.writeheader()
        writer.writerows(rows)


def format_summary(results: list[dict]) -> str:
    """One line per case: rate, cost per particle-step and its two big phases, memory, warm-up."""
    lines = ["", f"{'case':<16} {'particles':>10} {'p-steps/s':>10} {'ns/p-step':>9} "
             f"{'p2g ns':>7} {'g2p ns':>7} {'B/particle':>10} {'warm-up s':>9}"]
    for r in results:
        n = r["particles"] / r["ranks"]
        ph = r["phase_seconds_per_step"]
        lines.append(f"{r['dim']}D {r['method']} {r['update']:<5}".ljust(16)
                     + f" {r['particles']:>10,} {r['particle_steps_per_second']:>10.3e} "
                     f"{r['ns_per_particle_step']:>9.1f} {1e9 * ph['p2g'] / n:>7.1f} "
                     f"{1e9 * ph['g2p'] / n:>7.1f} {r['bytes_per_particle']:>10.0f} "
                     f"{r['jit_warmup_seconds']:>9.2f}")
    return "\n".join(lines)
