"""Collective measurements of a rank's state: separated pieces, metrics, totals, the gathered
particle fields, the decomposition report and the run's summary.

Functions of :class:`parmpm.driver.set_up.RankState` (``s``), apart from the run loop that steps it
(:mod:`parmpm.driver.simulation`): they read the state and change nothing but the metrics' record. Every
one is collective (every rank calls it) and reduces in patch order, so its result is the same on
any number of ranks.
"""
from __future__ import annotations

import numpy as np

from decomposition import max_and_patch_sum, ordered_sum
from parmpm.output import domains
from parmpm.core.collective import agree
from parmpm.output.connectivity import global_components, local_components, shared_pairs
from parmpm.core.errors import SimulationError
from parmpm.output.metrics.sums import patch_sums
from parmpm.transfer.reach import inverted_message, reach_message, support_reach
from parmpm.shapes import CPDI, CPDI2
from parmpm.shapes.cpdi2 import INVERTED
from parmpm.step.stepper import PHASES, WORK_PHASES


def components(s) -> int:
    """Connected pieces of material over all ranks (particles linked through grid nodes)."""
    P, D, ps = s.particles, s.disc, s.patches
    P.compact()  # rows in canonical order: ``nodes`` rows and the fields below agree
    # entries per particle: a tensor-product support reaches at most `ghost` cells past the
    # particle's cell on each side (farther is the reach error below), a CPDI one 2^d nodes
    # for each of 2^d corners, however far its domain reaches (a wider table would only be
    # page-faulted in: 46 MB, not 14, for 27,000 3D particles at a ghost width of 2)
    g = int(D.layout.ghost)
    box = int(np.prod(D.nloc[:s.dim]))  # nodes in a patch's ghost-inclusive box
    corners = D.method in (CPDI, CPDI2)
    K = min(box, 4 ** s.dim if corners else max(4 ** s.dim, (2 * g + 2) ** s.dim))
    # not zeroed: only a row's first count[p] entries are read (calloc's fresh pages fault in)
    nodes = np.empty((P.n, K), np.int64)
    count = np.zeros(P.n, np.int64)
    err = np.full(2, -1, np.int64)
    s.stepper.transfers.support_nodes(nodes, count, err)
    # A support past the ghost layer (inside the grid) would leave that particle without
    # nodes and fake a separation: stop with the reach error (the next p2g would raise it).
    # A support leaving the grid belongs to material on its way out: it counts as a piece of
    # its own, and the next step stops the run unless the separation stops it first.
    # (The message is the highest such rank's, as it always was; the stepper's own choice, the
    # first particle in (patch, id) order, would make it the same on any number of ranks.)
    inverted = int(err[0]) >= 0 and int(err[1]) == INVERTED
    bad = inverted or (int(err[0]) >= 0 and support_reach(s.stepper.disc, s.stepper.P.rows, int(err[0]))[1])
    problem = None
    if bad:
        st, i, phase = s.stepper, int(err[0]), "the separation check"
        problem = st.faults.error or (inverted_message(st.disc, st.P.rows, i, phase) if inverted
                               else reach_message(st.disc, st.P.rows, st.grid_phase.bc, i, phase))
    if s.size == 1:
        agree(s.comm, problem, root=None, error=SimulationError)
    k, pairs = 0, (np.zeros(0, np.int64), np.zeros(0, np.int64))
    if problem is None:
        # the nodes touched lie in this rank's patches' boxes, and are at most the entries
        k, label = local_components(nodes, count, max(1, min(int(count.sum()), ps.n_local * box)))
        if s.size == 1:
            return int(k)
        lay = D.layout
        pairs = shared_pairs(nodes, count, label, lay.global_nodes3, lay.psize3, lay.ghost3,
                             lay.patches_per_axis, ps.rank_of, s.rank)
    # one exchange for both: the problems (the highest rank's is raised, on every rank) and
    # every rank's pieces and shared nodes, merged alike on every rank
    parts = s.comm.allgather((-s.rank, problem, int(k), *pairs))
    found = [(key, p) for key, p, *_ in parts if p]
    if found:
        raise SimulationError(min(found, key=lambda kp: kp[0])[1])
    return global_components([rest for _, _, *rest in parts])


def sample_metrics(s) -> int:
    """Sample the scene's metrics; returns the number of connected pieces of material (1 when
    the metric does not look at separation: counting them costs 0.5-0.6 of the default scene's
    steps, docs/results/throughput.md)."""
    if s.metrics is None:
        return 1
    P = s.particles
    pieces = components(s) if s.metrics.needs_components else 1
    t = s.clock.t
    sums, maxes = s.metrics.terms(P.gid, P.x, P.v, P.F, t=t, particles=P,
                                  method=s.disc.method, lcr=s.disc.lcr,
                                  inertia=s.stepper.inertia)
    per_patch = patch_sums(P.start, np.ascontiguousarray(sums))
    maxes, total = max_and_patch_sum(s.comm, maxes, per_patch, s.patches.owner)
    s.metrics.record(t, total, maxes, pieces, v_time=t - 0.5 * s.clock.last_dt)
    return pieces


def totals(s) -> dict:
    """Mass, momentum and kinetic energy over all ranks (per-patch sums in patch order)."""
    P = s.particles
    terms = np.concatenate([P.mass[:, None], P.mass[:, None] * P.v,
                            0.5 * P.mass[:, None] * np.sum(P.v * P.v, axis=1, keepdims=True)], axis=1)
    total = ordered_sum(s.comm, s.patches.local_ids, patch_sums(P.start, terms))
    return {"mass": float(total[0]), "momentum": [float(c) for c in total[1:1 + s.dim]],
            "kinetic_energy": float(total[-1])}


def gather(s, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray] | None:
    """All particles' ``fields`` in global-id order on rank 0 (None elsewhere). Output only."""
    fields = dict(fields, _gid=s.particles.gid)
    parts = s.comm.gather(fields, root=0)
    if s.rank != 0:
        return None
    out = {k: np.concatenate([p[k] for p in parts]) for k in fields}
    order = np.argsort(out.pop("_gid"), kind="stable")
    return {k: v[order] for k, v in out.items()}


def axial_stretch(s) -> np.ndarray:
    """|F e_a| per particle of this rank: the stretch along the metrics' axis ``a``."""
    axis = s.spec.metrics.axis
    return np.linalg.norm(s.particles.F[:, :, axis], axis=1)


def domain_corners(s) -> np.ndarray | None:
    """(N, 4, 2) domain corners of this rank's particles as the interpolation sees them
    (scaled CPDI domains, cpGIMP boxes, ...; :mod:`parmpm.output.domains`); 2D only."""
    if s.dim != 2:
        return None
    P = s.particles
    return domains.domain_corners(2, s.disc.method, s.disc.lcr, P.x, P.F, P.r0, P.lh0,
                                  P.corners)


def decomposition_report(s) -> dict:
    """Patches, particles per rank, imbalance, ghost width and halo traffic (collective)."""
    ps, lay = s.patches, s.disc.layout
    plan = ps.plan
    d = s.dim
    comps = 1 + 2 * d if s.update == "usl" else 1 + 3 * d  # components accumulated
    comps_fill = 2 * d if s.update == "usl" else 3 * d     # components filled
    # bytes this rank sends per step: ghost boxes in accumulate, owned boxes in fill
    sent = 8 * (int(plan.ghost_seg_nodes.sum()) * comps + int(plan.own_seg_nodes.sum()) * comps_fill)
    local = {"patches": ps.n_local, "particles": int(s.particles.n), "sent": sent}
    rows = s.comm.allgather(local)
    loads = np.array([r["particles"] for r in rows], float)
    halo_bytes = sum(r["sent"] for r in rows)
    return {
        "ranks": s.size, "patches": int(ps.ids.size), "patches_dense": lay.n_patches,
        "patch_size": list(lay.patch_size), "ghost": lay.ghost,
        "patches_per_rank": [r["patches"] for r in rows],
        "particles_per_rank": [r["particles"] for r in rows],
        "imbalance": float(loads.max() / loads.mean() - 1.0) if loads.mean() > 0 else 0.0,
        "halo_bytes_per_step": int(halo_bytes),
        "rebalances": ps.rebalances, "patch_set_changes": ps.rebuilds,
    }


def summary(s, out_dir, stopped: str | None, wall: float, loop: float, warm_steps: int) -> dict:
    """The run's record for ``summary.json`` (collective; the same on every rank). ``stopped``:
    why the run stopped early (None: at its end), ``wall``: the run's wall time, ``loop``: the
    time of the ``warm_steps`` steps after the first."""
    spec, lay = s.spec, s.disc.layout
    timers = s.stepper.timers
    per_rank = np.array(s.comm.allgather([timers[k] for k in PHASES]))  # (ranks, phases)
    phase = per_rank.max(axis=0)
    # each rank's own work (the phases that wait for no one): how unevenly it is spread
    work = per_rank[:, [PHASES.index(k) for k in WORK_PHASES]].sum(axis=1)
    return {
        "scene": spec.name, "dim": s.dim, "method": s.interp.name,
        "lcr": s.lcr, "update": s.update, "flip": spec.method.flip,
        "transfer": spec.method.transfer,
        "ranks": s.size, "particles": s.n_total, "steps": s.clock.nstep, "time": s.clock.t,
        "stopped": stopped or "end",
        "output_dir": str(out_dir),
        "wall_seconds": wall,
        "particle_steps_per_second": (s.n_total * warm_steps / loop
                                      if warm_steps and loop > 0 else None),
        "grid": {"cells": [int(c) for c in s.disc.cells],
                 "exterior": [[int(c) for c in s.disc.exterior_lo],
                              [int(c) for c in s.disc.exterior_hi]],
                 "cell_size": list(map(float, s.disc.h)),
                 "patch_size": list(lay.patch_size), "patches": int(s.patches.ids.size),
                 "ghost": lay.ghost},
        "decomposition": decomposition_report(s),
        "final": totals(s),
        "energy": s.energy.report(),
        "phase_seconds_per_step": ({k: float(v) / warm_steps for k, v in zip(PHASES, phase)}
                                   if warm_steps else None),
        "rank_work_seconds_per_step": ({"min": float(work.min()) / warm_steps,
                                        "mean": float(work.mean()) / warm_steps,
                                        "max": float(work.max()) / warm_steps}
                                       if warm_steps else None),
        "metrics": s.metrics.result() if s.metrics is not None else {},
    }
