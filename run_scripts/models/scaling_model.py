"""The cost model (``cost_model.py``) confronted with ``scaling.py``'s measurements.

* :func:`partition_halo` — the halo bytes of a bench run from the face/edge/corner formula, on the
  patch partition the run starts from (rebuilt with ``decomposition``'s pure functions: the
  block's per-patch counts, the active patches, the Morton assignment); compared in
  ``scaling.csv`` with the halo code's own count ``halo_bytes_per_step``.
* :func:`fit_constants` — t_p per dimension, α and β (ping-pong), α_r (Allreduce) as measured.
* :func:`check_rows` — predicted against measured T and E at the measured rank counts.
* :func:`prediction_rows` — 3D cubes of N particles on many ranks of an assumed cluster, the load
  imbalance from a Morton split of the cube's patches (:func:`morton_imbalance`).
* :func:`model_study` — all of it: ``cost_model.csv``, ``cost_model.json``, ``cost_model.png``
  and the printed constants.

Driven by ``run_scripts/benchmarks/scaling.py`` (see its docstring for commands and outputs); no MPI here.
"""
from __future__ import annotations

import json
import math
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from models import cost_model as cm
import numpy as np
from study import compact_png, figure, save, write_csv


# --- the halo formula on the bench's own partition ---------------------------------------------
def partition_halo(result: dict, ranks: int) -> dict:
    """Halo bytes per step predicted by the face/edge/corner formula (``cost_model``) for the
    patch partition the bench starts from: the block's per-patch particle counts, the active
    patches and the Morton assignment are rebuilt with ``decomposition``'s pure functions.

    Returns the total over ranks (comparable with ``halo_bytes_per_step``), the busiest rank's
    bytes and neighbour-rank count, the number of shared patch faces across ranks and the
    bytes they alone account for."""
    from decomposition import PatchLayout, active_patches, assign
    from parmpm.cli.bench import build_bench_scene

    req, dim = result["request"], int(result["dim"])
    scene = build_bench_scene(dim, req["method"], req["particles"], req["ppc"], req["steps"],
                              req["patch_size"], req["speed"])
    grid, body = scene.data["grid"], scene.data["bodies"][0]
    layout = PatchLayout(tuple(result["grid"]["cells"]), tuple(result["grid"]["patch_size"]),
                         int(result["decomposition"]["ghost"]))
    g = layout.ghost
    if min(layout.patch_size) < g + 1:
        raise ValueError("the halo formula assumes patches of at least ghost + 1 cells")
    coords = layout.patch_coords()
    counts = np.full(layout.n_patches, float(req["ppc"]) ** dim)
    for a in range(dim):
        h, o = grid["cell_size"][a], grid["origin"][a]
        lo, hi = round((body["min"][a] - o) / h), round((body["max"][a] - o) / h)
        s = layout.patch_size[a]
        first = coords[:, a] * s
        counts *= np.clip(np.minimum(first + s, hi) - np.maximum(first, lo), 0, None)
    ids = active_patches(layout, np.flatnonzero(counts))
    rank_of = np.full(layout.n_patches, -1, np.int64)
    rank_of[ids] = assign(layout, ids, counts[ids], ranks)
    c_a, c_f = cm.halo_components(dim, result.get("update", "usl"))
    own_lo, own_hi = layout.owned_box(coords[ids])
    extent = (own_hi - own_lo)[:, :dim]
    sent = np.zeros(ranks)
    peers = [set() for _ in range(ranks)]
    faces, face_bytes = 0, 0
    nppa = layout.patches_per_axis
    for off in cm.neighbour_offsets(dim):
        o3 = np.array(list(off) + [0] * (3 - dim))
        qc = coords[ids] + o3
        ok = np.all((qc >= 0) & (qc < nppa), axis=1)
        q = np.where(ok, qc[:, 0] + nppa[0] * (qc[:, 1] + nppa[1] * qc[:, 2]), 0)
        ok &= rank_of[q] >= 0
        ok &= rank_of[q] != rank_of[ids]
        if not np.any(ok):
            continue
        p_idx = np.flatnonzero(ok)
        q_idx = np.searchsorted(ids, q[ok])
        # the rank of p sends: its ghost copy of q's owned box (accumulate), its owned box that q
        # holds as ghosts (fill)
        b = 8 * (c_a * cm.directed_halo_nodes(-np.array(off), extent[q_idx], g)
                 + c_f * cm.directed_halo_nodes(np.array(off), extent[p_idx], g))
        np.add.at(sent, rank_of[ids[p_idx]], b)
        for r, r2 in zip(rank_of[ids[p_idx]], rank_of[q[ok]]):
            peers[r].add(int(r2))
        if sum(map(abs, off)) == 1:
            faces += p_idx.size  # each shared face is seen from both sides: halved below
            face_bytes += int(b.sum())
    busiest = int(np.argmax(sent)) if ranks > 1 else 0
    return {"total": float(sent.sum()), "max_rank": float(sent.max()),
            "peers": max(len(p) for p in peers), "peers_of_busiest": len(peers[busiest]),
            "faces": faces // 2, "faces_only": float(face_bytes),
            "face_bytes": cm.face_halo_bytes(layout.patch_size[0], g, dim,
                                             result.get("update", "usl"))}


# --- the model -------------------------------------------------------------------------------------
def fit_constants(t_p: dict, probes: dict) -> tuple[cm.Machine, dict]:
    """(measured Machine, the JSON record of what was measured and how)."""
    pp = probes[2]["pingpong"]
    alpha, beta = cm.fit_latency_bandwidth(pp["bytes"], pp["seconds"])
    n, t = np.asarray(pp["bytes"], float), np.asarray(pp["seconds"], float)
    dev = float(np.max(np.abs((alpha + n / beta) / t - 1.0)))
    usable = {P: p for P, p in probes.items() if not p["oversubscribed"]} or probes
    alpha_r = cm.fit_reduction(list(usable), [p["allreduce"]["seconds"] for p in usable.values()])
    record = {
        "t_p_seconds": {str(d): v["t_p"] for d, v in t_p.items()},
        "t_p_source": {str(d): v["source"] for d, v in t_p.items()},
        "alpha_seconds": alpha, "beta_bytes_per_second": beta,
        "pingpong_fit_max_relative_error": dev,
        "alpha_r_seconds_per_stage": alpha_r,
        "allreduce_seconds": {str(P): p["allreduce"]["seconds"] for P, p in probes.items()},
        "allreduce_ranks_fitted": sorted(usable),
        "probe_oversubscribed": bool(probes[2]["oversubscribed"]),
        "mpi_library": probes[2]["mpi_library"],
    }
    return cm.Machine(alpha, beta, alpha_r), record


def check_rows(kind: str, results: list[dict], machine: cm.Machine, cores: int) -> list[dict]:
    """Predicted against measured T and E at the measured rank counts: this machine's constants,
    ``t_p`` of the series' own 1-rank run, the measured imbalance, the formula's halo bytes and
    neighbour ranks of the busiest rank."""
    base = min(results, key=lambda r: r["ranks"])
    t_p = cm.compute_time_per_particle(base)
    T1_pred, N1 = base["particles"] * t_p, base["particles"]
    rows = []
    for r in results:
        P, N = r["ranks"], r["particles"]
        hm = r.get("halo_model", {"max_rank": 0.0, "peers_of_busiest": 0})
        msgs = cm.halo_ops(r.get("update", "usl")) * hm["peers_of_busiest"]
        T = cm.step_time(N, P, t_p, machine, halo_bytes=hm["max_rank"], n_msg=msgs,
                         imbalance=r["decomposition"]["imbalance"] if P > 1 else 0.0)
        # strong: N = N1, E = T1/(P·T_P); weak: E = T1·N/(N1·P·T_P)
        e_pred = T1_pred * N / (N1 * P * T["total"])
        e_meas = base["seconds_per_step"] * N / (N1 * P * r["seconds_per_step"])
        rows.append({"kind": f"check_{kind}", "network": "measured", "dim": r["dim"],
                     "particles": float(N), "ranks": P, "oversubscribed": P > cores,
                     "patches": r["decomposition"]["patches"],
                     "patches_per_rank": r["decomposition"]["patches"] / P,
                     "imbalance": r["decomposition"]["imbalance"],
                     "halo_bytes": hm["max_rank"], "messages": msgs,
                     "seconds_per_step": T["total"], "efficiency": e_pred,
                     **{k: T[k] for k in ("compute_share", "latency_share", "bandwidth_share", "reduce_share")},
                     "measured_seconds_per_step": r["seconds_per_step"], "measured_efficiency": e_meas})
    return rows


def morton_imbalance(N: float, P: int, ppc: int, s: int, ghost: int, dim: int = 3) -> float:
    """Particle imbalance (max/mean − 1) of a cube of ``N`` particles (``N^(1/d)/ppc`` cells per
    axis from the origin, the last patch along an axis partial) whose occupied patches are split
    into ``P`` contiguous Morton pieces by ``decomposition.assign``, as a run starts."""
    from decomposition import PatchLayout, assign, imbalance

    n = max(1, round(N ** (1.0 / dim) / ppc))
    layout = PatchLayout((n,) * dim, (s,) * dim, ghost)
    coords = layout.patch_coords()[:, :dim]
    cells = np.prod(np.minimum(coords * s + s, n) - coords * s, axis=1)
    counts = cells.astype(float) * ppc ** dim
    if P > counts.size:
        return math.nan
    ids = np.arange(counts.size)
    owner = assign(layout, ids, counts, P)
    return imbalance(np.bincount(owner, weights=counts, minlength=P))


def prediction_rows(particles: list[float], ranks: list[int], t_p: float, machines: dict,
                    geo: dict) -> list[dict]:
    rows = []
    imb = {(N, P): morton_imbalance(N, P, geo["ppc"], geo["patch_size"], geo["ghost"])
           for N in particles for P in ranks}
    for label, machine in machines.items():
        for N in particles:
            for P in ranks:
                p = cm.predict_cube(N, P, t_p, machine, dim=3, ppc=geo["ppc"], s=geo["patch_size"],
                                    ghost=geo["ghost"], drift=geo["drift_cells_per_step"],
                                    imbalance=imb[N, P] if math.isfinite(imb[N, P]) else None)
                rows.append({"kind": "prediction", "network": label, "dim": 3, "particles": N,
                             "ranks": P, "oversubscribed": False, "patches": p["patches"],
                             "patches_per_rank": p["patches_per_rank"], "imbalance": p["imbalance"],
                             "halo_bytes": p["halo_bytes"], "messages": p["messages"],
                             "seconds_per_step": p["total"], "efficiency": p["efficiency"],
                             **{k: p[k] for k in ("compute_share", "latency_share",
                                                  "bandwidth_share", "reduce_share")},
                             "measured_seconds_per_step": math.nan, "measured_efficiency": math.nan,
                             "migration_bytes": p["migration_bytes"]})
    return rows


# --- the model study ---------------------------------------------------------------------------
def model_study(args, results: dict, rows: list[dict], t_p: dict, probes: dict, out: Path,
                figs: Path) -> tuple[list[dict], Path]:
    """Fit, check and predict; write ``cost_model.csv`` / ``.json`` / ``.png``; returns (check
    rows, PNG path). ``results``: bench results per kind (each with its ``halo_model``),
    ``rows``: their ``scaling.csv`` rows in the same order."""
    from parmpm.scene.schema import DEFAULT_PATCH_SIZE
    from parmpm.shapes import INTERPOLATORS

    kinds = list(results)
    cores = os.cpu_count() or 1
    machine, measured = fit_constants(t_p, probes)
    net = cm.network_machine(machine, args.alpha_net, args.beta_net)
    geo = {"dim": 3, "method": "cpdi", "ppc": args.ppc, "patch_size": DEFAULT_PATCH_SIZE[3],
           "ghost": INTERPOLATORS["cpdi"].ghost_width(2.0, 1.0),  # l_cr = 2Δx
           "halo_doubles_per_node": list(cm.halo_components(3)), "messages_per_neighbour": cm.halo_ops(),
           "drift_cells_per_step": args.drift, "alpha_net": args.alpha_net, "beta_net": args.beta_net}
    geo["face_halo_bytes"] = cm.face_halo_bytes(geo["patch_size"], geo["ghost"], 3)
    tp_pred = geo["t_p"] = t_p.get(3, t_p[args.dim])["t_p"]
    checks = [c for kind in kinds for c in check_rows(kind, results[kind], machine, cores)]
    pred = prediction_rows([float(x) for x in args.predict_particles.split(",")],
                           [int(float(p)) for p in args.predict_ranks.split(",")], tp_pred,
                           {"assumed_ib": net, "measured": machine}, geo)
    write_csv(out / "cost_model.csv", [dict(c, migration_bytes=0.0) for c in checks] + pred)
    halo_check = []
    for r, res in zip(rows, [x for k in kinds for x in results[k]]):
        if r["ranks"] > 1:
            measured_bytes, hm = r["halo_bytes_per_step"], res["halo_model"]
            halo_check.append({
                "kind": r["kind"], "ranks": r["ranks"], "measured_bytes": measured_bytes,
                "formula_bytes": r["halo_bytes_model"],
                "ratio": r["halo_bytes_model"] / measured_bytes if measured_bytes else None,
                "faces": hm["faces"], "faces_only_bytes": hm["faces_only"], "face_bytes": hm["face_bytes"]})
    record = {
        "note": (f"measured on {platform.node()} ({cores} cores) {time.strftime('%Y-%m-%d %H:%M')}; "
                 "single runs on a shared machine are noisy: quote as preliminary"),
        "quick": bool(args.quick),
        "measured": measured,
        "assumed": {"alpha_net_seconds": args.alpha_net, "beta_net_bytes_per_second": args.beta_net,
                    "network": "100 Gb/s InfiniBand (assumed, not measured)",
                    "imbalance": "Morton split of the cube's patches (decomposition.assign)",
                    "drift_cells_per_step": args.drift,
                    "subdomains": "cubes of patches, every neighbour rank off-node"},
        "prediction_machine": net.as_dict(), "measured_machine": machine.as_dict(),
        "t_p_used_for_prediction": tp_pred, "t_p_dim_used_for_prediction": 3 if 3 in t_p else args.dim,
        "geometry": geo,
        "halo_check": halo_check,
        "check": [{k: c[k] for k in ("kind", "ranks", "particles", "seconds_per_step",
                                     "measured_seconds_per_step", "efficiency", "measured_efficiency")}
                  for c in checks],
    }
    (out / "cost_model.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    print_model(record, checks, pred)
    return checks, chart_model(pred, geo, figs / "cost_model.png")


def chart_model(pred: list[dict], geo: dict, path: Path) -> Path:
    fig, axes = figure(1, 2, size=(10.5, 4.2))
    ax_e, ax_s = axes[0]
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]
    sizes = sorted({r["particles"] for r in pred})
    for i, N in enumerate(sizes):
        rr = sorted((r for r in pred if r["particles"] == N and r["network"] == "assumed_ib"),
                    key=lambda r: r["ranks"])
        ok = [r for r in rr if math.isfinite(r["efficiency"])]
        if not ok:
            continue
        c = colours[i % len(colours)]
        P = [r["ranks"] for r in ok]
        ax_e.plot(P, [r["efficiency"] for r in ok], "-o", ms=4, color=c, label=f"N = {N:.0e}")
        ax_e.plot(P, [1.0 / (1.0 + r["imbalance"]) for r in ok], ":", color=c, lw=1)
        ax_s.plot(P, [1.0 - r["compute_share"] for r in ok], "-o", ms=4, color=c, label=f"N = {N:.0e}")
        if len(ok) < len(rr):
            ax_e.annotate(f"more ranks than its {rr[0]['patches']:.0f} patches",
                          (ok[-1]["ranks"], ok[-1]["efficiency"]), fontsize=7,
                          xytext=(-30, -14), textcoords="offset points", color=c)
    ax_e.plot([], [], ":", color="0.4", lw=1, label="imbalance alone: 1/(1+ι)")
    for ax in (ax_e, ax_s):
        ax.set_xscale("log")
        ax.set_xlabel("MPI ranks")
        ax.grid(alpha=0.3, which="both")
    ax_e.axhline(1.0, color="k", ls=":", lw=0.8)
    ax_e.set_ylim(0, 1.05)
    ax_e.set_ylabel("predicted strong-scaling efficiency")
    ax_e.set_title(f"3D cpdi cube, ppc {geo['ppc']}, patches {geo['patch_size']}³, ghost {geo['ghost']}",
                   fontsize=9)
    ax_s.set_yscale("log")
    ax_s.set_ylabel("communication share of the step")
    ax_s.set_title(f"assumed α_net {geo['alpha_net'] * 1e6:g} µs, β_net {geo['beta_net'] / 1e9:g} GB/s; "
                   f"measured t_p {geo['t_p'] * 1e6:.3g} µs", fontsize=9)
    ax_e.legend(fontsize=7, loc="lower left")
    ax_s.legend(fontsize=7)
    return compact_png(save(fig, path))


def print_model(record: dict, checks: list[dict], pred: list[dict]) -> None:
    m = record["measured"]
    print("\ncost model constants (measured on this machine unless marked assumed):")
    for d, v in m["t_p_seconds"].items():
        print(f"  t_p ({d}D)        {v * 1e9:8.1f} ns per particle-step   [{m['t_p_source'][d]}]")
    print(f"  alpha           {m['alpha_seconds'] * 1e6:8.2f} µs   beta {m['beta_bytes_per_second'] / 1e9:.2f} GB/s "
          f"(ping-pong fit, worst size off by {100 * m['pingpong_fit_max_relative_error']:.0f} %)")
    print(f"  alpha_r         {m['alpha_r_seconds_per_stage'] * 1e6:8.2f} µs per log2 P stage "
          f"(Allreduce of 5 doubles on {m['allreduce_ranks_fitted']} ranks)")
    a = record["assumed"]
    print(f"  assumed network: alpha_net {a['alpha_net_seconds'] * 1e6:g} µs, "
          f"beta_net {a['beta_net_bytes_per_second'] / 1e9:g} GB/s ({a['network']})")
    for h in record["halo_check"]:
        ratio = "n/a" if h["ratio"] is None else f"{h['ratio']:.4f}"
        print(f"  halo check ({h['kind']}, {h['ranks']} ranks): measured {h['measured_bytes']:,} B/step, "
              f"formula {h['formula_bytes']:,.0f} (ratio {ratio}); {h['faces']} shared faces × "
              f"{h['face_bytes']:,} B = {h['faces_only_bytes']:,.0f}, the rest edges/corners")
    print("\ncheck at the measured points (this machine's constants):")
    for c in checks:
        print(f"  {c['kind']:>12} P={c['ranks']:<3} T pred {c['seconds_per_step']:.4g} s, meas "
              f"{c['measured_seconds_per_step']:.4g} s;  E pred {c['efficiency']:.3f}, meas "
              f"{c['measured_efficiency']:.3f}" + ("  (oversubscribed)" if c["oversubscribed"] else ""))
    print("\npredicted strong-scaling efficiency, 3D cpdi cube (assumed network):")
    sizes = sorted({r["particles"] for r in pred})
    ranks = sorted({r["ranks"] for r in pred})
    print("  " + f"{'ranks':>7}" + "".join(f"{f'N={N:.0e}':>12}" for N in sizes))
    for P in ranks:
        cells = []
        for N in sizes:
            r = next(r for r in pred if r["ranks"] == P and r["particles"] == N and r["network"] == "assumed_ib")
            cells.append(f"{r['efficiency']:>12.3f}" if math.isfinite(r["efficiency"]) else f"{'> patches':>12}")
        print("  " + f"{P:>7}" + "".join(cells))
