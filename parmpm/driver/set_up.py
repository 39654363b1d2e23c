"""Set-up: a resolved scene, a communicator and optionally a checkpoint become this rank's state.

:func:`set_up` builds the discretisation (with the patch size ``grid.patch_size = "auto"``
chooses from the scene, :mod:`parmpm.scene.patch_size`), deals the patches out over the ranks (rank 0
warns when some start without particles) and gives this rank its particles
(:mod:`parmpm.driver.rank_particles`), by one of three paths: seeded from the scene (every rank counts the same particles per patch, block by block,
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
from dataclasses import dataclass, replace

import numpy as np

from decomposition import PatchSet, allreduce_max, ranks_on_this_node
from parmpm.loads import manufactured
from parmpm.core.collective import agree
from parmpm.transfer.discretisation import Discretisation, exterior_cells
from parmpm.output.energy import EnergyWatch
from parmpm.core.errors import ParmpmError, SceneError
from parmpm.driver.footprint import check_memory
from parmpm.driver.rank_particles import carried_fields, rank_particles
from parmpm.grid.update import BC_CODES
from parmpm.grid.symmetry import check_blocks
from parmpm.core.log import get_logger
from parmpm.materials import PARAM, material_table
from parmpm.particles.store import Particles
from parmpm.scene.patch_size import (TARGET_PATCHES, auto_patch_size, covered_patches, floor_size)
from parmpm.scene.records import Boundary, Grid, SceneSpec
from parmpm.scene.recorded_files import body_records
from parmpm.scene.schema import DEFAULT_PATCH_SIZE
from parmpm.driver.schedule import Clock
from parmpm.shapes import CAPPED, INTERPOLATORS
from parmpm.shapes.cpdi2 import affine_corners
from parmpm.step.stepper import Stepper
from parmpm.step.contact import ContactPhase
from parmpm.step.walls import WallPhase
from parmpm.driver.external import external_loads
from parmpm.materials.passes import max_speed
from parmpm.materials.plasticity.state import initial_state
from parmpm.materials.plasticity.table import plastic_table
from parmpm.materials.plasticity.update import plastic_pass

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
    material_rows: dict       # material name -> its row of the table
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
    body_ranges: list          # every body's global ids [first, last): seeded or checkpointed
    body_records: list         # what the checkpoints record of them (scene.recorded_files)

    @property
    def spec(self) -> SceneSpec:
        """The scene's records (what the run reads)."""
        return self.scene.spec

    @property
    def data(self) -> dict:
        """The scene's serialised form (:attr:`parmpm.scene.load.Scene.data`)."""
        return self.scene.data

    @property
    def dim(self) -> int:
        return self.scene.spec.dim

    @property
    def rank(self) -> int:
        return self.comm.Get_rank()

    @property
    def size(self) -> int:
        return self.comm.Get_size()


def sparse_mls_warnings(spec: SceneSpec) -> list[str]:
    """One line per body seeded with one particle per cell along some axis under MLS, whose
    force one point per cell integrates poorly (docs/mls.md: diverged on the manufactured
    solution, the static bar separated)."""
    if spec.method.transfer != "mls":
        return []
    return [f"bodies.{k}.ppc = {list(b.ppc)} with method.transfer = \"mls\": one particle per "
            "cell integrates the MLS force poorly (docs/mls.md: the manufactured solution "
            "diverged); use 2 or more"
            for k, b in enumerate(spec.bodies) if b.ppc is not None and min(b.ppc) < 2]


def set_up(scene, comm, checkpoint=None) -> RankState:
    """This rank's state of ``scene`` (collective); ``checkpoint``: an open
    :class:`parmpm.io.checkpoint_parts.CheckpointReader` to continue from."""
    spec = scene.spec
    interp = INTERPOLATORS[spec.method.interpolator]
    lcr = scene.lcr if interp.code in CAPPED else None
    D = _discretisation(comm, spec, interp, lcr)
    bc, region_box, region_normal = _boundary(spec.boundary, spec.dim)
    cut = check_blocks(D.layout, D.face_lo3, D.face_hi3, bc)
    if cut is not None:
        raise SceneError(f"scene '{scene.source}': {cut}")
    params, names = material_table(spec.materials)
    plastic = plastic_table(spec.materials, names)
    rows = {n: i for i, n in enumerate(names)}
    P, patches, n_total, metrics, ranges = rank_particles(spec, comm, D, params, rows,
                                                          checkpoint, plastic is not None,
                                                          scene.source)
    had = P.optional
    # a checkpoint of an older format may lack one: zeros
    P.carry(carried_fields(spec.method, plastic is not None))
    if "corners" in P.optional and "corners" not in had:  # e.g. a cpdi run continued as cpdi2
        P.corners[:] = affine_corners(P.F, P.r0)
    vmax_plastic = 0.0
    if plastic is not None and (checkpoint is None or "plastic" not in had):
        P.plastic[:] = initial_state(P.n)  # virgin; the stress of the seeded F (0 at F = I)
        vmax_plastic = plastic_pass(spec.dim, P.F, P.mat, plastic, P.plastic, P.stress, P.v, 0.0)
    if comm.Get_rank() == 0:
        for line in sparse_mls_warnings(spec):
            logger.warning(line)
    m = spec.method
    update = m.update if m.update != "auto" else ("usl" if interp.code in CAPPED else "musl")
    stepper = Stepper(D, P, patches, params, bc, region_box, update,
                      1.0 if m.flip is None else m.flip, spec.damping.coefficient, n_total,
                      region_normal, m.transfer)
    if spec.manufactured:
        _manufactured(stepper, spec.dim, params, spec.manufactured.amplitude)
    stepper.plastic = plastic
    if spec.time.dt is not None:
        stepper.fix_step()
    if spec.walls:
        stepper.walls = WallPhase(spec.walls, spec.dim)
    if spec.contact:
        stepper.use_contact(_contact(spec, ranges))
    if spec.loads:
        stepper.forcing = external_loads(spec, comm, P, ranges, n_total)
        stepper.load_work = True
    limit = spec.time.max_energy_growth
    driven = stepper.forcing is not None or (stepper.walls is not None and stepper.walls.moves)
    energy = EnergyWatch(None if driven or limit == "off" else limit)
    # the run's identity: its folder's marker and its checkpoints carry it, so that pruning
    # touches only its own checkpoints (parmpm.io.run_folder); a restart is a run of its own
    run_id = comm.bcast(uuid.uuid4().hex if comm.Get_rank() == 0 else None, root=0)
    clock, continues, next_output = _clock(scene, comm, D, P, params, metrics, energy,
                                           checkpoint, vmax_plastic)
    return RankState(scene, comm, interp, lcr, update, D, params, rows, patches, P, stepper,
                     n_total, metrics, energy, clock, run_id, checkpoint is not None, continues,
                     next_output, ranges, body_records(spec.bodies, ranges))


def _contact(spec: SceneSpec, ranges: list) -> ContactPhase:
    """The contact phase of ``[contact]``: every body's field and first global id."""
    body_start = [first for first, _ in ranges] + [ranges[-1][1]]
    reach = 1.5 if spec.method.interpolator == "bspline" else 1.0  # support past the domain
    c = spec.contact
    return ContactPhase(c.field_of_body(len(spec.bodies)), body_start, c.mu, reach, spec.dim,
                        c.crack_damage if c.cracks else None, c.normal, c.gap)


def _discretisation(comm, spec: SceneSpec, interp, lcr: float | None) -> Discretisation:
    """The grid, its exterior layer and the patches (the size ``grid.patch_size = "auto"``
    chooses), after the memory check: before anything of the scene's size is allocated."""
    ghost = spec.grid.ghost
    if ghost == "auto":
        ghost = interp.ghost_width(lcr, spec.min_dx)
    ghost = int(ghost)
    exterior = exterior_cells(spec.grid, spec.bodies, ghost)
    grid = _patch_size(comm, spec, ghost, exterior)
    _check_memory(comm, replace(spec, grid=grid), ghost)
    # the patches cover the grid and its exterior layer (grid.exterior), the face conditions
    # stay on the user's faces (parmpm.transfer.discretisation.exterior_cells)
    return Discretisation.from_grid(spec.dim, interp.code, lcr, grid, ghost, exterior)


def _clock(scene, comm, D, P, params, metrics, energy, checkpoint, vmax_plastic=0.0):
    """(the clock, the run a restart continues, the output schedule's next time): a fresh run's
    (``vmax_plastic``: the plastic particles' largest ``c + |v|``, which the elastic table
    leaves out), or a restart's, whose metrics and energy watch are restored too."""
    tm = scene.spec.time  # the Time record: cfl, dt_max, dt, end, steps
    h_min = float(D.h.min())
    if checkpoint is None:
        vmax = max(max_speed(D.dim, P.v, P.F, P.mat, params), vmax_plastic)
        return (Clock(tm, h_min, float(allreduce_max(comm, np.array([vmax]))[0]),
                      speaks=comm.Get_rank() == 0), None, None)
    a = checkpoint.attrs
    clock = Clock(tm, h_min, float(a["vmax"]), float(a["time"]), int(a["step"]),
                  float(a["dt"]), speaks=comm.Get_rank() == 0)
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
    return clock, continues, next_output


def _patch_size(comm, spec: SceneSpec, ghost: int, exterior) -> Grid:
    """The grid the run lays out: ``patch_size = "auto"`` replaced by the size
    :func:`parmpm.scene.patch_size.auto_patch_size` chooses from the scene (the resolved scene keeps
    "auto": a restart chooses the same)."""
    grid = spec.grid
    if grid.patch_size != "auto":
        return grid
    size = auto_patch_size(spec, ghost, exterior)
    if comm.Get_rank() == 0:
        logger.info("grid.patch_size = %s chosen from the scene (its bodies cover %d such "
                    "patches; the default %d is halved, down to %d, while they cover fewer than "
                    "%d); set grid.patch_size to fix it", "x".join(map(str, size)),
                    covered_patches(spec, max(size), exterior), DEFAULT_PATCH_SIZE[spec.dim],
                    floor_size(spec.dim, ghost), TARGET_PATCHES)
    return replace(grid, patch_size=tuple(size))


def _check_memory(comm, spec: SceneSpec, ghost: int) -> None:
    """Refuse, on every rank, a scene this node's ranks cannot hold (:mod:`parmpm.driver.footprint`)."""
    problem = None
    try:
        check_memory(spec, ghost, comm.Get_size(), ranks_on_this_node(comm))
    except ParmpmError as exc:
        problem = str(exc)
    agree(comm, problem, root=None)


def _boundary(boundary: Boundary, d: int):
    """(face codes (3, 2), region boxes (R, 2, 3), region normals (R,): -1 fixed, k slip)."""
    bc = np.zeros((3, 2), np.int64)
    for k, (lo, hi) in enumerate(boundary.faces):
        bc[k] = [BC_CODES[lo], BC_CODES[hi]]
    regions = boundary.fixed_regions + boundary.slip_regions
    region_box = np.zeros((len(regions), 2, 3))
    region_normal = np.full(len(regions), -1, np.int64)  # -1: fixed, k: slip with normal k
    for r, reg in enumerate(regions):
        region_box[r, 0, :d], region_box[r, 1, :d] = reg.min, reg.max
    for r, reg in enumerate(boundary.slip_regions, start=len(boundary.fixed_regions)):
        region_normal[r] = "xyz".index(reg.normal)
    return bc, region_box, region_normal


def _manufactured(stepper: Stepper, d: int, params: np.ndarray, A: float) -> None:
    """Drive the run with the manufactured solution's body force (:mod:`parmpm.loads.manufactured`)."""
    c, row = manufactured.frequency(params), params[0]
    lam, mu, rho = row[PARAM["lam"]], row[PARAM["mu"]], row[PARAM["density"]]
    stepper.forcing = lambda t, P, out: manufactured.body_force(d, P.x0, t, A, c, lam, mu, rho, out)

