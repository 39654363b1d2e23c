"""Set-up: a resolved scene, a communicator and optionally a checkpoint become this rank's state.

:func:`set_up` builds the discretisation (with the patch size ``grid.patch_size = "auto"``
chooses from the scene, :mod:`parmpm.scene.patch_size`), deals the patches out over the ranks (rank 0
warns when some start without particles) and gives this rank its particles, by one of three
paths: seeded from the scene (every rank counts the same particles per patch, block by block,
global ids = seeding order, and builds only its own: a rank never holds the whole scene;
:mod:`parmpm.particles.seeding`), seeded and set on the manufactured solution's exact field (patches where
the particles start), or read back from a checkpoint (:mod:`parmpm.driver.checkpoint_writer`). A
seeded run's metrics are built from each rank's own particles by collective reductions. A restart also restores the clock, the metrics' history,
the energy watch and the output schedule, so that it continues bit for bit. The run loop
(:mod:`parmpm.driver.simulation`) and the measurements (:mod:`parmpm.driver.measures`) read the result,
:class:`RankState`; nothing here steps or writes.
"""
from __future__ import annotations

import uuid
from dataclasses import dataclass

import numpy as np

from decomposition import PatchSet, allreduce_max, ranks_on_this_node
from parmpm.loads import manufactured
from parmpm.transfer.affine import AFFINE_TRANSFERS
from parmpm.scene.overlaps import check_overlaps
from parmpm.core.collective import agree
from parmpm.transfer.discretisation import Discretisation, exterior_cells
from parmpm.output.energy import EnergyWatch
from parmpm.core.errors import ParmpmError, SceneError, SimulationError
from parmpm.exact.bars import manufactured_motion
from parmpm.driver.footprint import check_memory
from parmpm.grid.update import BC_CODES
from parmpm.grid.symmetry import check_blocks
from parmpm.driver.checkpoint_writer import load_patches, load_rows
from parmpm.io.checkpoint import attrs_digest
from parmpm.io.checkpoint_parts import CheckpointReader
from parmpm.core.log import get_logger
from parmpm.materials import PARAM, material_table
from parmpm.output.metrics import make_metrics
from parmpm.particles.store import Particles, locate_patches
from parmpm.scene.patch_size import (TARGET_PATCHES, auto_patch_size, covered_patches, floor_size,
                               idle_ranks_warning)
from parmpm.transfer.reach import fmt_vec
from parmpm.driver.restart_keys import check_restart
from parmpm.scene.load import scene_from_toml
from parmpm.scene.agreement import check_same_scene
from parmpm.scene.schema import DEFAULT_PATCH_SIZE
from parmpm.driver.schedule import Clock
from parmpm.particles.seeding import seed_bodies
from parmpm.shapes import CAPPED, CPDI2, INTERPOLATORS
from parmpm.shapes.cpdi2 import affine_corners
from parmpm.step.stepper import Stepper
from parmpm.transfer.generic import max_speed

logger = get_logger(__name__)


@dataclass
class RankState:
    """Everything one rank holds of a run: its particles and patches, the stepper that advances
    them, the clock, and the run-wide objects every rank keeps alike (metrics, energy watch)."""

    scene: object
    comm: object
    interp: object            # the interpolator's registry entry (name, code, ghost width)
    lcr: float | None         # the CPDI/CPDI2 cap (None: neither, or no cap)
    update: str               # "usl" or "musl"
    disc: Discretisation
    params: np.ndarray        # material table
    patches: PatchSet
    particles: Particles
    stepper: Stepper
    n_total: int              # particles on all ranks
    metrics: object           # the scene's metrics (None when there are none)
    energy: EnergyWatch
    clock: Clock
    run_id: str               # this run's identity (a restart is a run of its own)
    restart: bool             # continued from a checkpoint
    continues: dict | None    # the run a restart continues: its id and the checkpoint
    next_output: float | None  # the output schedule's next time, as checkpointed

    @property
    def data(self) -> dict:
        return self.scene.data

    @property
    def dim(self) -> int:
        return self.scene.data["dim"]

    @property
    def rank(self) -> int:
        return self.comm.Get_rank()

    @property
    def size(self) -> int:
        return self.comm.Get_size()


def carried_fields(data: dict) -> tuple[str, ...]:
    """The optional particle fields (:data:`parmpm.particles.store.OPTIONAL_FIELDS`) a resolved scene
    needs: ``affine`` under APIC and MLS, ``corners`` under cpdi2."""
    method = data["method"]
    return tuple(k for k, used in (("affine", method["transfer"] in AFFINE_TRANSFERS),
                                   ("corners", INTERPOLATORS[method["interpolator"]].code == CPDI2))
                 if used)


def sparse_mls_warnings(data: dict) -> list[str]:
    """One line per body seeded with one particle per cell along some axis under MLS, whose
    force one point per cell integrates poorly (docs/mls.md: diverged on the manufactured
    solution, the static bar separated)."""
    if data["method"]["transfer"] != "mls":
        return []
    return [f"bodies.{k}.ppc = {b['ppc']} with method.transfer = \"mls\": one particle per cell "
            "integrates the MLS force poorly (docs/mls.md: the manufactured solution diverged); "
            "use 2 or more"
            for k, b in enumerate(data["bodies"]) if min(b["ppc"]) < 2]


def set_up(scene, comm, checkpoint=None) -> RankState:
    """This rank's state of ``scene`` (collective); ``checkpoint``: an open
    :class:`parmpm.io.checkpoint_parts.CheckpointReader` to continue from."""
    data = scene.data
    d = data["dim"]
    interp = INTERPOLATORS[data["method"]["interpolator"]]
    lcr = scene.lcr if interp.code in CAPPED else None
    ghost = data["grid"]["ghost"]
    if ghost == "auto":
        ghost = interp.ghost_width(lcr, scene.min_dx)
    exterior = exterior_cells(data, int(ghost))
    grid = _patch_size(comm, data, int(ghost), exterior)
    # before anything of the scene's size is allocated
    _check_memory(comm, {**data, "grid": grid}, int(ghost))
    # the patches cover the grid and its exterior layer (grid.exterior), the face conditions
    # stay on the user's faces (parmpm.transfer.discretisation.exterior_cells)
    D = Discretisation.from_grid(d, interp.code, lcr, grid, int(ghost), exterior)
    bc, region_box, region_normal = _boundary(data, d)
    cut = check_blocks(D.layout, D.face_lo3, D.face_hi3, bc)
    if cut is not None:
        raise SceneError(f"scene '{scene.source}': {cut}")
    params, names = material_table(data["materials"])
    P, patches, n_total, metrics = _particles(data, comm, D, params, names, checkpoint)
    had = P.optional
    P.carry(carried_fields(data))  # a checkpoint of an older format may lack one: zeros
    if "corners" in P.optional and "corners" not in had:  # e.g. a cpdi run continued as cpdi2
        P.corners[:] = affine_corners(P.F, P.r0)
    m = data["method"]
    if comm.Get_rank() == 0:
        for line in sparse_mls_warnings(data):
            logger.warning(line)
    update = m["update"] if m["update"] != "auto" else ("usl" if interp.code in CAPPED else "musl")
    stepper = Stepper(D, P, patches, params, bc, region_box, update, m.get("flip", 1.0),
                      data["damping"]["coefficient"], n_total, region_normal, m["transfer"])
    if data.get("manufactured"):
        _manufactured(stepper, d, params, data["manufactured"]["amplitude"])
    limit = data["time"]["max_energy_growth"]
    limit = None if limit == "off" else limit
    energy = EnergyWatch(None if stepper.forcing is not None else limit)
    # the run's identity: its folder's marker and its checkpoints carry it, so that pruning
    # touches only its own checkpoints (parmpm.io.run_folder); a restart is a run of its own
    run_id = comm.bcast(uuid.uuid4().hex if comm.Get_rank() == 0 else None, root=0)
    h_min = float(D.h.min())
    continues, next_output = None, None
    if checkpoint is None:
        vmax = max_speed(d, P.v, P.F, P.mat, params)
        clock = Clock(data["time"], h_min, float(allreduce_max(comm, np.array([vmax]))[0]))
    else:
        a = checkpoint.attrs
        clock = Clock(data["time"], h_min, float(a["vmax"]), float(a["time"]), int(a["step"]),
                      float(a["dt"]))
        state = checkpoint.state
        next_output = state.get("next_output")
        changed = (scene.restart or {}).get("changed", {})
        if "output.every" in changed or "output.every_steps" in changed:
            next_output = None  # a new series from here, not the stored schedule's next time
        if metrics is not None and state.get("metrics"):
            metrics.restore(state["metrics"])
        energy.restore(state.get("energy"))
        continues = {"run_id": (state.get("run") or {}).get("id"),
                     "checkpoint": str(checkpoint.path), "changed": changed}
    return RankState(scene, comm, interp, lcr, update, D, params, patches, P, stepper, n_total,
                     metrics, energy, clock, run_id, checkpoint is not None, continues,
                     next_output)


def open_checkpoint(path, overrides, comm):
    """(scene, reader) of the run saved in ``path``: its stored scene with ``overrides`` applied
    (e.g. ``time.end=...``; only the keys :mod:`parmpm.driver.restart_keys` allows, recorded in
    ``scene.restart``); the caller closes the reader. Collective under ``comm``: a rank's problem
    is raised on every rank, and the ranks must continue the same checkpoint with the same scene
    (:func:`parmpm.scene.agreement.check_same_scene`)."""
    reader, scene, problem = None, None, None
    try:
        reader = CheckpointReader(path, warn=comm is None or comm.Get_rank() == 0)
        text = str(reader.attrs["scene"])
        stored = scene_from_toml(text, f"{path}")
        scene = scene_from_toml(text, f"{path}", overrides)
        if scene.data["dim"] != int(reader.attrs["dim"]):
            raise ParmpmError(f"checkpoint '{path}' holds a {int(reader.attrs['dim'])}D run; "
                              f"dim cannot change on restart (got dim = {scene.data['dim']})")
        check_restart(path, stored, scene, overrides, int(reader.attrs["step"]),
                      float(reader.attrs["time"]))
    except ParmpmError as exc:
        if comm is None:
            if reader is not None:
                reader.close()
            raise
        problem = str(exc)
    except BaseException:
        if reader is not None:
            reader.close()
        raise
    try:
        if comm is not None:
            agree(comm, problem, root=None)
            # the same checkpoint (its attributes' digest covers its data's) and the same scene
            check_same_scene(comm, scene, f"step {int(reader.attrs['step'])}, attributes "
                             f"{attrs_digest(reader.attrs)[:12]}", what=f"'{path}'")
    except BaseException:
        if reader is not None:
            reader.close()
        raise
    return scene, reader


def _patch_size(comm, data: dict, ghost: int, exterior) -> dict:
    """The ``[grid]`` table the run lays out: ``patch_size = "auto"`` replaced by the size
    :func:`parmpm.scene.patch_size.auto_patch_size` chooses from the scene (the resolved scene keeps
    "auto": a restart chooses the same)."""
    grid = data["grid"]
    if grid["patch_size"] != "auto":
        return grid
    size = auto_patch_size(data, ghost, exterior)
    if comm.Get_rank() == 0:
        logger.info("grid.patch_size = %s chosen from the scene (its bodies cover %d such "
                    "patches; the default %d is halved, down to %d, while they cover fewer than "
                    "%d); set grid.patch_size to fix it", "x".join(map(str, size)),
                    covered_patches(data, max(size), exterior), DEFAULT_PATCH_SIZE[data["dim"]],
                    floor_size(data["dim"], ghost), TARGET_PATCHES)
    return {**grid, "patch_size": size}


def _check_memory(comm, data: dict, ghost: int) -> None:
    """Refuse, on every rank, a scene this node's ranks cannot hold (:mod:`parmpm.driver.footprint`)."""
    problem = None
    try:
        check_memory(data, ghost, comm.Get_size(), ranks_on_this_node(comm))
    except ParmpmError as exc:
        problem = str(exc)
    agree(comm, problem, root=None)


def _particles(data, comm, D, params, names, checkpoint):
    """(this rank's particles, the patch set, particles in all, metrics): seeded from the scene
    (:func:`_seeded`) or read back from a checkpoint (:func:`_restored`)."""
    if checkpoint is None:
        return _seeded(data, comm, D, params, names)
    return _restored(data, comm, D, params, checkpoint)


def _seeded(data, comm, D, params, names):
    """Seeded: every rank counts the particles per patch block by block (global ids = seeding
    order), deals the patches out, then builds only its own (:mod:`parmpm.particles.seeding`) and the
    metrics from them (collective): a rank holds one block of seeds and its own particles."""
    layout, d = D.layout, data["dim"]
    seeds = seed_bodies(data, {n: i for i, n in enumerate(names)})
    man = data.get("manufactured")
    if man:  # the particles start on the exact field: their patches are where they start
        amplitude, c = man["amplitude"], manufactured.frequency(params)
        seeds.motion = lambda X: X + manufactured_motion(X, 0.0, amplitude, c)[0]
    counts = seeds.patch_counts(D)
    dec = data["decomposition"]
    patches = PatchSet(layout, comm, counts, threshold=dec["rebalance_threshold"],
                       cooldown=dec["rebalance_cooldown"])
    _warn_idle_ranks(comm, D, counts, seeds)
    P = seeds.particles(params, seeds.members(D, patches.rank_of == comm.Get_rank()),
                        carried_fields(data))
    check_overlaps(comm, data, seeds, P.gid, P.x0)  # bodies seeded twice: one warning each
    if man:
        manufactured.initialise(P, man["amplitude"], params)
        if "corners" in P.optional:  # the domains of the initial F
            P.corners[:] = affine_corners(P.F, P.r0)
    locate_patches(d, P.x, D.origin3, D.inv_h3, layout.cells3, layout.psize3,
                   layout.patches_per_axis, P.patch, P.patch)
    metrics = make_metrics(data, P.x0, P.mass, comm, P.gid)
    return P, patches, seeds.n, metrics


def _restored(data, comm, D, params, checkpoint):
    """Read back from a checkpoint. Version 4 on the same patch grid (the grid is chosen from
    the scene alone, so a restart has the checkpoint's unless it overrides the grid): the
    index's counts deal the patches out and each rank reads exactly its patches' rows, then
    checks that each particle lies in the patch the index says. Otherwise (versions 1–3, or
    another grid) every rank reads every position to find the patches, then its own rows."""
    layout, d = D.layout, data["dim"]
    rank, n_materials = comm.Get_rank(), params.shape[0]
    indexed = checkpoint.indexed_for(D)
    if indexed:
        counts, where = checkpoint.patch_counts(), None
    else:
        if checkpoint.version >= 4 and rank == 0:
            logger.info("%s was written on another patch grid: every rank reads every position "
                        "to find the patches", checkpoint.path)
        x_all = checkpoint.read("x")
        where = np.zeros(x_all.shape[0], np.int64)
        bad, _ = locate_patches(d, x_all, D.origin3, D.inv_h3, layout.cells3, layout.psize3,
                                layout.patches_per_axis, where, where)
        if bad >= 0:
            raise SimulationError(f"particle {bad} at {fmt_vec(x_all[bad])} is outside the grid")
        counts = np.bincount(where, minlength=layout.n_patches)
        del x_all
    dec = data["decomposition"]
    patches = PatchSet(layout, comm, counts, threshold=dec["rebalance_threshold"],
                       cooldown=dec["rebalance_cooldown"])
    _warn_idle_ranks(comm, D, counts, _StoredPositions(checkpoint))
    owned = patches.rank_of == rank
    if indexed:
        P = load_patches(comm, checkpoint, d, n_materials, np.flatnonzero(owned))
        _check_patches(comm, D, P, checkpoint)
    else:
        mine = np.flatnonzero(owned[where])
        P = load_rows(comm, checkpoint, d, n_materials, mine, where[mine])
    metrics = make_metrics(data, P.x0, P.mass, comm, P.gid)
    return P, patches, checkpoint.n, metrics


def _check_patches(comm, D: Discretisation, P: Particles, checkpoint) -> None:
    """Every particle read by the index lies in the patch the index files it under (one line
    on every rank otherwise: a damaged index)."""
    lay = D.layout
    at = np.zeros(P.n, np.int64)
    locate_patches(D.dim, P.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                   lay.patches_per_axis, at, at)
    wrong = np.flatnonzero(at != P.patch)
    problem = None
    if wrong.size:
        i = int(wrong[0])
        problem = (f"checkpoint '{checkpoint.path}': damaged: its index files particle "
                   f"{int(P.gid[i])} under patch {int(P.patch[i])}, but it lies in patch {int(at[i])}")
    agree(comm, problem, root=None)


class _StoredPositions:
    """A checkpoint's positions for the idle-ranks advice (:func:`_warn_idle_ranks`), read only
    if rank 0 has advice to give (some ranks start without particles)."""

    def __init__(self, checkpoint):
        self.checkpoint = checkpoint

    def patch_counts(self, D: Discretisation) -> np.ndarray:
        lay = D.layout
        x = self.checkpoint.read("x")
        at = np.zeros(x.shape[0], np.int64)
        locate_patches(D.dim, x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                       lay.patches_per_axis, at, at)
        return np.bincount(at, minlength=lay.n_patches)


def _warn_idle_ranks(comm, D: Discretisation, counts: np.ndarray, where) -> None:
    """Rank 0 warns, in one line with the computed fix, when some ranks start without particles
    (more ranks than patches holding them): the run stays correct, those ranks just wait.
    ``where``: the particles' positions, or the :class:`parmpm.particles.seeding.Seeds` that counted them
    per axis."""
    if comm.Get_rank() != 0 or comm.Get_size() == 1:
        return

    def count_at(size: int):
        other = D.with_patch_size(size)
        lay = other.layout
        if not isinstance(where, np.ndarray):
            return lay, where.patch_counts(other)
        at = np.zeros(where.shape[0], np.int64)
        locate_patches(D.dim, where, other.origin3, other.inv_h3, lay.cells3, lay.psize3,
                       lay.patches_per_axis, at, at)
        return lay, np.bincount(at, minlength=lay.n_patches)

    line = idle_ranks_warning(D.layout, counts, comm.Get_size(), D.dim, count_at)
    if line is not None:
        logger.warning(line)


def _boundary(data: dict, d: int):
    """(face codes (3, 2), region boxes (R, 2, 3), region normals (R,): -1 fixed, k slip)."""
    bc = np.zeros((3, 2), np.int64)
    for k, axis in enumerate("xyz"[:d]):
        bc[k] = [BC_CODES[data["boundary"][f"{axis}_min"]], BC_CODES[data["boundary"][f"{axis}_max"]]]
    regions = data["boundary"]["fixed_regions"] + data["boundary"]["slip_regions"]
    region_box = np.zeros((len(regions), 2, 3))
    region_normal = np.full(len(regions), -1, np.int64)  # -1: fixed, k: slip with normal k
    for r, reg in enumerate(regions):
        region_box[r, 0, :d], region_box[r, 1, :d] = reg["min"], reg["max"]
        if "normal" in reg:
            region_normal[r] = "xyz".index(reg["normal"])
    return bc, region_box, region_normal


def _manufactured(stepper: Stepper, d: int, params: np.ndarray, A: float) -> None:
    """Drive the run with the manufactured solution's body force (:mod:`parmpm.loads.manufactured`)."""
    c, row = manufactured.frequency(params), params[0]
    lam, mu, rho = row[PARAM["lam"]], row[PARAM["mu"]], row[PARAM["density"]]
    stepper.forcing = lambda t, P, out: manufactured.body_force(d, P.x0, t, A, c, lam, mu, rho, out)

