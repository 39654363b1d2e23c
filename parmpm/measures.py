"""Collective measurements of a run's state: separated pieces, metrics, totals, the gathered
particle fields and the decomposition report.

A mixin of :class:`parmpm.simulation.Simulation`, split off along the seam between *stepping* a
run (set-up, clock, output, checkpoints: ``simulation.py``) and *measuring* it. Every method is
collective (every rank calls it) and reduces in patch order, so its result is the same on any
number of ranks. It reads the simulation's ``particles``, ``disc``, ``patches``, ``comm``,
``metrics``, ``stepper``, ``data``, ``t``, ``last_dt`` and ``update`` (and, for the summary, the
run's identity, clock and energy watch).
"""
from __future__ import annotations

import numpy as np

from decomposition import allreduce_max, ordered_sum
from parmpm.errors import SimulationError
from parmpm.reach import reach_message, support_reach
from parmpm.stepper import PHASES, WORK_PHASES
from parmpm.transfer import support_nodes


class Measures:
    """Collective measurements (see the module doc)."""

    def components(self) -> int:
        """Connected pieces of material over all ranks (particles linked through grid nodes)."""
        from parmpm.connectivity import compact_nodes, global_components, local_components, shared_pairs

        P, D, ps = self.particles, self.disc, self.patches
        # entries per particle: a tensor-product support reaches at most `ghost` cells past the
        # particle's cell on each side (farther is the reach error below), a CPDI one 2^d nodes
        # for each of 2^d corners
        g = int(D.layout.ghost)
        K = min(int(np.prod(D.nloc[:self.dim])), max(4 ** self.dim, (2 * g + 2) ** self.dim))
        nodes = np.zeros((P.n, K), np.int64)
        count = np.zeros(P.n, np.int64)
        err = np.full(1, -1, np.int64)
        support_nodes(D.method, D.dim, D.lcr, P.start, D.base, D.nloc, D.nglob, D.origin3,
                      D.inv_h3, P.x, P.F, P.r0, P.lh0, nodes, count, err)
        # A support past the ghost layer (inside the grid) would leave that particle without
        # nodes and fake a separation: stop with the reach error (the next p2g would raise it).
        # A support leaving the grid belongs to material on its way out: it counts as a piece of
        # its own, and the next step stops the run unless the separation stops it first.
        bad = int(err[0]) >= 0 and support_reach(self.stepper, int(err[0]))[1]
        if bad and self.stepper.error is None:
            self.stepper.error = reach_message(self.stepper, int(err[0]), "the separation check")
        failed = allreduce_max(self.comm, np.array([self.rank + 1.0 if bad else 0.0]))[0]
        if failed > 0:
            raise SimulationError(self.comm.bcast(self.stepper.error, root=int(failed) - 1))
        compact, n_nodes = compact_nodes(nodes, count)
        k, label = local_components(compact, count, n_nodes)
        if self.size == 1:
            return int(k)
        lay = D.layout
        pairs = shared_pairs(nodes, count, label, lay.global_nodes3, lay.psize3, lay.ghost3,
                             lay.patches_per_axis, ps.rank_of, self.rank)
        return global_components(self.comm, int(k), pairs)

    def sample_metrics(self) -> int:
        """Sample the scene's metrics; returns the number of connected pieces of material (1 when
        the metric does not look at separation: counting them costs about a time step)."""
        if self.metrics is None:
            return 1
        from parmpm.metrics import patch_sums

        P = self.particles
        pieces = self.components() if self.metrics.needs_components else 1
        sums, maxes = self.metrics.terms(P.gid, P.x, P.v, P.F, t=self.t, particles=P,
                                         method=self.disc.method, lcr=self.disc.lcr)
        per_patch = patch_sums(P.start, np.ascontiguousarray(sums))
        total = ordered_sum(self.comm, self.patches.local_ids, per_patch)
        maxes = allreduce_max(self.comm, maxes) if maxes.size else maxes
        self.metrics.record(self.t, total, maxes, pieces, v_time=self.t - 0.5 * self.last_dt)
        return pieces

    def totals(self) -> dict:
        """Mass, momentum and kinetic energy over all ranks (per-patch sums in patch order)."""
        from parmpm.metrics import patch_sums

        P = self.particles
        terms = np.concatenate([P.mass[:, None], P.mass[:, None] * P.v,
                                0.5 * P.mass[:, None] * np.sum(P.v * P.v, axis=1, keepdims=True)], axis=1)
        total = ordered_sum(self.comm, self.patches.local_ids, patch_sums(P.start, terms))
        return {"mass": float(total[0]), "momentum": [float(c) for c in total[1:1 + self.dim]],
                "kinetic_energy": float(total[-1])}

    def gather(self, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray] | None:
        """All particles' ``fields`` in global-id order on rank 0 (None elsewhere). Output only."""
        fields = dict(fields, _gid=self.particles.gid)
        parts = self.comm.gather(fields, root=0)
        if self.rank != 0:
            return None
        out = {k: np.concatenate([p[k] for p in parts]) for k in fields}
        order = np.argsort(out.pop("_gid"), kind="stable")
        return {k: v[order] for k, v in out.items()}

    def axial_stretch(self) -> np.ndarray:
        axis = self.data["metrics"]["axis"]
        return np.linalg.norm(self.particles.F[:, :, axis], axis=1)

    def domain_corners(self) -> np.ndarray | None:
        """(N, 4, 2) domain corners of this rank's particles as the interpolation sees them
        (scaled CPDI domains, cpGIMP boxes, ...; :mod:`parmpm.domains`); 2D only."""
        if self.dim != 2:
            return None
        from parmpm.domains import domain_corners

        P = self.particles
        return domain_corners(2, self.disc.method, self.disc.lcr, P.x, P.F, P.r0, P.lh0)

    def decomposition_report(self) -> dict:
        """Patches, particles per rank, imbalance, ghost width and halo traffic (collective)."""
        ps, lay = self.patches, self.disc.layout
        plan = ps.plan
        d = self.dim
        comps = 1 + 2 * d if self.update == "usl" else 1 + 3 * d  # components accumulated
        comps_fill = 2 * d if self.update == "usl" else 3 * d     # components filled
        # bytes this rank sends per step: ghost boxes in accumulate, owned boxes in fill
        sent = 8 * (int(plan.ghost_seg_nodes.sum()) * comps + int(plan.own_seg_nodes.sum()) * comps_fill)
        local = {"patches": ps.n_local, "particles": int(self.particles.n), "sent": sent}
        rows = self.comm.allgather(local)
        loads = np.array([r["particles"] for r in rows], float)
        halo_bytes = sum(r["sent"] for r in rows)
        return {
            "ranks": self.size, "patches": int(ps.ids.size), "patches_dense": lay.n_patches,
            "patch_size": list(lay.patch_size), "ghost": lay.ghost,
            "patches_per_rank": [r["patches"] for r in rows],
            "particles_per_rank": [r["particles"] for r in rows],
            "imbalance": float(loads.max() / loads.mean() - 1.0) if loads.mean() > 0 else 0.0,
            "halo_bytes_per_step": int(halo_bytes),
            "rebalances": ps.rebalances, "patch_set_changes": ps.rebuilds,
        }

    def summary(self, wall: float, loop: float, warm_steps: int) -> dict:
        """The run's record for ``summary.json`` (collective; the same on every rank). ``wall``:
        the run's wall time, ``loop``: the time of the ``warm_steps`` steps after the first."""
        data, lay = self.data, self.disc.layout
        timers = self.stepper.timers
        per_rank = np.array(self.comm.allgather([timers[k] for k in PHASES]))  # (ranks, phases)
        phase = per_rank.max(axis=0)
        # each rank's own work (the phases that wait for no one): how unevenly it is spread
        work = per_rank[:, [PHASES.index(k) for k in WORK_PHASES]].sum(axis=1)
        return {
            "scene": data["name"], "dim": self.dim, "method": self.interp.name,
            "lcr": self.lcr, "update": self.update, "flip": data["method"]["flip"],
            "ranks": self.size, "particles": self.n_total, "steps": self.nstep, "time": self.t,
            "stopped": self.stopped or "end",
            "output_dir": str(self.out_dir),
            "wall_seconds": wall,
            "particle_steps_per_second": (self.n_total * warm_steps / loop
                                          if warm_steps and loop > 0 else None),
            "grid": {"cells": [int(c) for c in self.disc.cells],
                     "exterior": [[int(c) for c in self.disc.exterior_lo],
                                  [int(c) for c in self.disc.exterior_hi]],
                     "cell_size": list(map(float, self.disc.h)),
                     "patch_size": list(lay.patch_size), "patches": int(self.patches.ids.size),
                     "ghost": lay.ghost},
            "decomposition": self.decomposition_report(),
            "final": self.totals(),
            "energy": self.energy.report(),
            "phase_seconds_per_step": ({k: float(v) / warm_steps for k, v in zip(PHASES, phase)}
                                       if warm_steps else None),
            "rank_work_seconds_per_step": ({"min": float(work.min()) / warm_steps,
                                            "mean": float(work.mean()) / warm_steps,
                                            "max": float(work.max()) / warm_steps}
                                           if warm_steps else None),
            "metrics": self.metrics.result() if self.metrics is not None else {},
        }
