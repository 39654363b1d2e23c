"""The run loop: owns time (Δt from CFL, stop criteria), not physics.

``Simulation(scene, out_dir).run()`` builds particles and patches from the resolved scene, steps
until ``time.end`` or ``time.steps``, samples the scene's metrics, writes snapshots (XDMF),
``summary.json`` and a figure, and returns the summary. Output and metrics are callbacks on the
clock; a non-finite velocity stops the run with a clear error (NaN check on by default).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from decomposition import PatchLayout
from parmpm.errors import ParmpmError, SimulationError
from parmpm.grid import BC_CODES
from parmpm.log import get_logger
from parmpm.materials import material_table
from parmpm.particles import bodies_to_particles
from parmpm.progress import Progress
from parmpm.shapes import CPDI, INTERPOLATORS, domain_matrix
from parmpm.stepper import Discretisation, Stepper
from parmpm.transfer import max_speed, support_nodes

log = get_logger(__name__)


class Simulation:
    """One run of a resolved scene on this process's patches."""

    def __init__(self, scene, out_dir=None, quiet: bool = False, comm=None):
        self.scene = scene
        self.data = data = scene.data
        self.out_dir = Path(out_dir) if out_dir else Path("parmpm-out") / scene.name
        self.quiet = quiet
        self.comm = comm
        d = self.dim = data["dim"]
        grid = data["grid"]
        interp = INTERPOLATORS[data["method"]["interpolator"]]
        self.interp = interp
        self.lcr = scene.lcr if interp.code == CPDI else None
        ghost = grid["ghost"]
        if ghost == "auto":
            ghost = interp.ghost_width(self.lcr, scene.min_dx)
        layout = PatchLayout(tuple(grid["cells"]), tuple(grid["patch_size"]), int(ghost))
        self.disc = Discretisation(d, interp.code, self.lcr or 0.0,
                                   np.asarray(grid["origin"], float),
                                   np.asarray(grid["cell_size"], float), layout)
        self.params, names = material_table(data["materials"])
        self.particles = bodies_to_particles(data, {n: i for i, n in enumerate(names)}, self.params)
        P = self.particles
        bc = np.zeros((3, 2), np.int64)
        for k, axis in enumerate("xyz"[:d]):
            bc[k] = [BC_CODES[data["boundary"][f"{axis}_min"]], BC_CODES[data["boundary"][f"{axis}_max"]]]
        regions = np.zeros((len(data["boundary"]["fixed_regions"]), 2, 3))
        for r, reg in enumerate(data["boundary"]["fixed_regions"]):
            regions[r, 0, :d], regions[r, 1, :d] = reg["min"], reg["max"]
        m = data["method"]
        self.update = m["update"] if m["update"] != "auto" else ("usl" if interp.code == CPDI else "musl")
        self.stepper = Stepper(self.disc, P, self.params, bc, regions, self.update, m["flip"],
                               data["damping"]["coefficient"])
        # initial stress from the initial F (identity → zero for the elastic models)
        self.t, self.nstep, self.last_dt = 0.0, 0, 0.0
        self.vmax = max_speed(d, P.v, P.F, P.mat, self.params)
        order = np.argsort(P.gid)
        from parmpm.metrics import make_metrics
        self.metrics = make_metrics(data, P.x0[order], P.mass[order])

    # --- clock --------------------------------------------------------------------------------
    def next_dt(self) -> float:
        tm = self.data["time"]
        dt = tm["cfl"] * float(self.disc.h.min()) / self.vmax
        if tm["dt_max"]:
            dt = min(dt, tm["dt_max"])
        if tm["end"] is not None:
            dt = min(dt, tm["end"] - self.t)
        return dt

    def done(self) -> bool:
        tm = self.data["time"]
        if tm["steps"] is not None and self.nstep >= tm["steps"]:
            return True
        return tm["end"] is not None and self.t >= tm["end"] * (1 - 1e-12)

    def gravity(self, t: float) -> np.ndarray:
        g = self.data["gravity"]
        ramp = g["ramp_time"]
        f = min(1.0, t / ramp) if ramp > 0 else 1.0
        return np.concatenate([np.asarray(g["g"], float) * f, np.zeros(3 - self.dim)])

    # --- callbacks ----------------------------------------------------------------------------
    def components(self) -> int:
        """Connected pieces of material (particles linked through shared grid nodes)."""
        from parmpm.metrics import count_components

        P, D = self.particles, self.disc
        K = max(64, int(np.prod(D.nloc[:self.dim])))
        nodes = np.zeros((P.n, K), np.int64)
        count = np.zeros(P.n, np.int64)
        err = np.full(1, -1, np.int64)
        support_nodes(D.method, D.dim, D.lcr, P.start, D.base, D.nloc, D.nglob, D.origin3,
                      D.inv_h3, P.x, P.F, P.r0, P.lh0, nodes, count, err)
        return count_components(nodes, count, int(np.prod(D.nglob)))

    def sample_metrics(self) -> int:
        """Sample the scene's metrics; returns the number of connected pieces of material."""
        if self.metrics is None:
            return 1
        P = self.particles
        o = np.argsort(P.gid)
        pieces = self.components()
        self.metrics.sample(self.t, P.x[o], P.v[o], P.F[o], pieces,
                            v_time=self.t - 0.5 * self.last_dt)
        return pieces

    def axial_stretch(self) -> np.ndarray:
        axis = self.data["metrics"]["axis"]
        return np.linalg.norm(self.particles.F[:, :, axis], axis=1)

    def domain_corners(self) -> np.ndarray | None:
        """(N, 4, 2) CPDI domain corners (scaled domains as the interpolation sees them), 2D."""
        if self.dim != 2 or self.disc.method != CPDI:
            return None
        P = self.particles
        R = np.zeros((3, 3))
        corners = np.zeros((P.n, 4, 2))
        signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
        for i in range(P.n):  # output only, not on the time-step path
            domain_matrix(2, CPDI, self.disc.lcr, P.F[i], P.r0[i], R)
            corners[i] = P.x[i] + signs @ R[:2, :2].T
        return corners

    def snapshot(self, writer) -> None:
        if writer is None:
            return
        P = self.particles
        o = np.argsort(P.gid)
        writer.write(self.t, P.x[o], {
            "gid": P.gid[o].astype(float), "velocity": P.v[o],
            "stress": P.stress[o].reshape(P.n, -1), "stretch": self.axial_stretch()[o],
            "damage": P.damage[o], "rank": np.zeros(P.n)})

    # --- ranks ----------------------------------------------------------------------------------
    def run_on_world(self) -> dict:
        """Run under MPI_COMM_WORLD. Until the patch decomposition spreads patches over ranks
        (the MPI issue), rank 0 runs every patch and the other ranks wait without spinning."""
        try:
            from mpi4py import MPI
        except ImportError:
            return self.run()
        comm = MPI.COMM_WORLD
        if comm.Get_size() == 1:
            return self.run()
        if comm.Get_rank() == 0:
            log.warning("patches are not yet distributed over ranks: rank 0 runs all %d patches "
                        "on %d ranks", self.disc.layout.n_patches, comm.Get_size())
            summary = self.run()
            summary["ranks"] = comm.Get_size()
            comm.Ibarrier().Wait()
        else:
            req = comm.Ibarrier()
            while not req.Test():
                time.sleep(0.02)
            summary = None
        return comm.bcast(summary, root=0)

    # --- the loop -----------------------------------------------------------------------------
    def run(self) -> dict:
        from parmpm.io.summary import write_summary
        from parmpm.io.xdmf import SnapshotWriter

        data, P = self.data, self.particles
        out = data["output"]
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ParmpmError(f"cannot create output folder '{self.out_dir}': {exc.strerror}") from None
        writer = SnapshotWriter(self.out_dir, data["name"], self.dim) if out["snapshots"] else None
        every_t, every_n = out["every"], out["every_steps"]
        next_out = every_t if every_t else math.inf
        me = data["metrics"]["every_steps"]
        stop_on_sep = data["metrics"]["stop_on_separation"]
        self.stopped = None
        progress = Progress(total_steps=data["time"]["steps"], end_time=data["time"]["end"],
                            enabled=not self.quiet)
        wall0 = time.perf_counter()
        warm_wall, warm_steps = None, 0
        try:
            self.sample_metrics()
            self.snapshot(writer)
            while not self.done():
                dt = self.next_dt()
                self.vmax = self.stepper.step(dt, self.gravity(self.t))
                self.t += dt
                self.nstep += 1
                self.last_dt = dt
                if not math.isfinite(self.vmax):
                    raise SimulationError(f"non-finite velocity or stress at step {self.nstep} "
                                          f"(t = {self.t:.6g} s); try a smaller time.cfl")
                if warm_wall is None:
                    warm_wall = time.perf_counter()  # the first step includes JIT compilation
                else:
                    warm_steps += 1
                if self.nstep % me == 0 and self.sample_metrics() > 1 and stop_on_sep:
                    self.stopped = "separated"
                    log.info("material separated at t = %.6g s: stopping (metrics.stop_on_separation)", self.t)
                    self.snapshot(writer)
                    break
                due = (every_n and self.nstep % every_n == 0) or self.t >= next_out * (1 - 1e-12)
                if due or self.done():
                    self.snapshot(writer)
                    while next_out <= self.t * (1 + 1e-12):
                        next_out += every_t
                elapsed = time.perf_counter() - (warm_wall or wall0)
                rate = P.n * warm_steps / elapsed if warm_steps and elapsed > 0 else 0.0
                progress.update(self.nstep, self.t, rate)
        finally:
            progress.close()
            if writer is not None:
                writer.close()
        wall = time.perf_counter() - wall0
        loop = time.perf_counter() - warm_wall if warm_wall else wall
        summary = {
            "scene": data["name"], "dim": self.dim, "method": self.interp.name,
            "lcr": self.lcr, "update": self.update, "flip": data["method"]["flip"],
            "ranks": 1, "particles": P.n, "steps": self.nstep, "time": self.t,
            "stopped": self.stopped or "end",
            "wall_seconds": wall,
            "particle_steps_per_second": P.n * warm_steps / loop if warm_steps and loop > 0 else None,
            "grid": {"cells": list(self.disc.layout.cells), "cell_size": list(map(float, self.disc.h)),
                     "patch_size": list(self.disc.layout.patch_size),
                     "patches": self.disc.layout.n_patches, "ghost": self.disc.layout.ghost},
            "metrics": self.metrics.result() if self.metrics is not None else {},
        }
        write_summary(self.out_dir, summary)
        if out["figure"]:
            from parmpm.io.figures import plot_particles
            o = np.argsort(P.gid)
            corners = self.domain_corners()
            plot_particles(self.out_dir / f"{data['name']}.png", P.x[o], self.axial_stretch()[o],
                           self.dim, corners=None if corners is None else corners[o],
                           title=f"{data['name']} · {self.interp.name} · t = {self.t:.3g} s")
        return summary
