"""This rank's particles at set-up: seeded from the scene or read back from a checkpoint.

Seeded (:func:`_seeded`): every rank counts the particles per patch block by block (global ids
= seeding order), the patches are dealt out, and each rank builds only its own
(:mod:`parmpm.particles.seeding`); a particle file is read by rank 0 and dealt out
(:mod:`parmpm.driver.listed_share`), a mesh is made P ways (:mod:`parmpm.driver.mesh_slices`).
Read back (:func:`_restored`): on the checkpoint's patch grid each rank reads exactly its
patches' rows through the index, otherwise every rank reads every position to find the patches.
Either way rank 0 warns, with the computed fix, when some ranks start without particles.
Split from :mod:`parmpm.driver.set_up`, which builds the rest of a rank's state around these.
"""
from __future__ import annotations

import numpy as np

from decomposition import PatchSet
from parmpm.core.collective import agree
from parmpm.core.errors import SimulationError
from parmpm.core.log import get_logger
from parmpm.driver.checkpoint_writer import load_patches, load_rows
from parmpm.driver.listed_share import counted_by_root, seeded_by_root, share_listed, shared_listing
from parmpm.driver.mesh_slices import make_mesh_slices
from parmpm.exact.bars import manufactured_motion
from parmpm.loads import manufactured
from parmpm.output.history import body_ranges
from parmpm.output.metrics import make_metrics
from parmpm.particles.locate import locate_patches
from parmpm.particles.seeding import seed_bodies
from parmpm.particles.store import Particles
from parmpm.scene.overlaps import check_overlaps
from parmpm.scene.patch_size import idle_ranks_warning
from parmpm.scene.recorded_files import remember
from parmpm.scene.records import Method, SceneSpec
from parmpm.scene.wall_checks import check_walls
from parmpm.shapes import CPDI2, INTERPOLATORS
from parmpm.shapes.cpdi2 import affine_corners
from parmpm.transfer.affine import AFFINE_TRANSFERS
from parmpm.transfer.discretisation import Discretisation
from parmpm.transfer.reach import fmt_vec

logger = get_logger(__name__)


def carried_fields(method: Method, plastic: bool = False) -> tuple[str, ...]:
    """The optional particle fields (:data:`parmpm.particles.store.OPTIONAL_FIELDS`) a scene
    needs: ``affine`` under APIC and MLS, ``corners`` under cpdi2, ``plastic`` with a plastic
    material."""
    return tuple(k for k, used in (("affine", method.transfer in AFFINE_TRANSFERS),
                                   ("corners", INTERPOLATORS[method.interpolator].code == CPDI2),
                                   ("plastic", plastic))
                 if used)


def rank_particles(spec, comm, D, params, rows, checkpoint, plastic=False, source=""):
    """(this rank's particles, the patch set, particles in all, metrics, every body's global-id
    range): seeded from the scene (:func:`_seeded`) or read back from a checkpoint
    (:func:`_restored`), whose ranges are its own, not the input files' of today."""
    if checkpoint is None:
        return _seeded(spec, comm, D, params, rows, plastic, source)
    out = _restored(spec, comm, D, params, checkpoint)
    return (*out, _stored_ranges(spec, rows, checkpoint, out[2]))


def _stored_ranges(spec: SceneSpec, rows: dict, checkpoint, n: int) -> list:
    """The bodies' global-id ranges a checkpoint records (:mod:`parmpm.scene.recorded_files`);
    one written before it recorded them: found by seeding the scene again, as then."""
    ranges = remember(checkpoint.state.get("bodies"))
    if ranges is None:
        return body_ranges(spec.grid, spec.bodies, rows)
    if len(ranges) != len(spec.bodies) or ranges[-1][1] != n:
        raise SimulationError(f"checkpoint '{checkpoint.path}': damaged: its body records give "
                              f"{len(ranges)} bodies and {ranges[-1][1]} particles, the run "
                              f"{len(spec.bodies)} and {n}")
    return ranges


def _patch_set(spec: SceneSpec, comm, layout, counts) -> PatchSet:
    dec = spec.decomposition
    return PatchSet(layout, comm, counts, threshold=dec.rebalance_threshold,
                    cooldown=dec.rebalance_cooldown)


def _seeded(spec: SceneSpec, comm, D, params, rows, plastic=False, scene_source=""):
    """Seeded: every rank counts the particles per patch block by block (global ids = seeding
    order), deals the patches out, then builds only its own (:mod:`parmpm.particles.seeding`) and the
    metrics from them (collective): a rank holds one block of seeds and its own particles. With
    a particle-file body on several ranks, rank 0 alone reads the file, counts and sends every
    rank its own rows (:mod:`parmpm.driver.listed_share`); a mesh body's particles are made P
    ways, each rank its slice of the elements, and sent to their patches' ranks
    (:mod:`parmpm.driver.mesh_slices`)."""
    layout, d = D.layout, spec.dim
    shared = shared_listing(comm, spec.bodies)  # particle files: read by rank 0 only
    seeds = (seeded_by_root(comm, spec.grid, spec.bodies, rows) if shared
             else seed_bodies(spec.grid, spec.bodies, rows))
    man = spec.manufactured
    if man:  # the particles start on the exact field: their patches are where they start
        amplitude, c = man.amplitude, manufactured.frequency(params)
        seeds.motion = lambda X: X + manufactured_motion(X, 0.0, amplitude, c)[0]
    slices = make_mesh_slices(comm, seeds, D, scene_source) if shared else None  # meshes: P ways
    counts = counted_by_root(comm, seeds, D) if shared else seeds.patch_counts(D)
    if slices:
        counts = counts + slices.patch_counts(comm, D)
    patches = _patch_set(spec, comm, layout, counts)
    _warn_idle_ranks(comm, D, counts, seeds, slices)
    if shared:  # each rank receives its own particles' rows
        share_listed(comm, seeds, D, patches.rank_of)
        slices.share(comm, patches.rank_of)
    P = seeds.particles(params, seeds.members(D, patches.rank_of == comm.Get_rank()),
                        carried_fields(spec.method, plastic))
    check_overlaps(comm, spec, seeds, P.gid, P.x0)  # bodies seeded twice: one warning each
    check_walls(comm, spec, seeds, P.gid, P.x0)  # walls that cut, hide or miss: one line each
    if man:
        manufactured.initialise(P, man.amplitude, params)
        if "corners" in P.optional:  # the domains of the initial F
            P.corners[:] = affine_corners(P.F, P.r0)
    locate_patches(d, P.x, D.origin3, D.inv_h3, layout.cells3, layout.psize3,
                   layout.patches_per_axis, P.patch, P.patch)
    metrics = make_metrics(spec, P.x0, P.mass, comm, P.gid)
    ends = np.cumsum([len(chunk[0]) for chunk in seeds.chunks])
    ranges = [(int(e - len(c[0])), int(e)) for e, c in zip(ends, seeds.chunks)]
    return P, patches, seeds.n, metrics, ranges


def _restored(spec: SceneSpec, comm, D, params, checkpoint):
    """Read back from a checkpoint. Version 4 on the same patch grid (the grid is chosen from
    the scene alone, so a restart has the checkpoint's unless it overrides the grid): the
    index's counts deal the patches out and each rank reads exactly its patches' rows, then
    checks that each particle lies in the patch the index says. Otherwise (versions 1–3, or
    another grid) every rank reads every position to find the patches, then its own rows."""
    layout, d = D.layout, spec.dim
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
    patches = _patch_set(spec, comm, layout, counts)
    _warn_idle_ranks(comm, D, counts, _StoredPositions(checkpoint))
    owned = patches.rank_of == rank
    if indexed:
        P = load_patches(comm, checkpoint, d, n_materials, np.flatnonzero(owned))
        _check_patches(comm, D, P, checkpoint)
    else:
        mine = np.flatnonzero(owned[where])
        P = load_rows(comm, checkpoint, d, n_materials, mine, where[mine])
    metrics = make_metrics(spec, P.x0, P.mass, comm, P.gid)
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


def _warn_idle_ranks(comm, D: Discretisation, counts: np.ndarray, where, slices=None) -> None:
    """Rank 0 warns, in one line with the computed fix, when some ranks start without particles
    (more ranks than patches holding them): the run stays correct, those ranks just wait.
    ``where``: the particles' positions, or the :class:`parmpm.particles.seeding.Seeds` that counted them
    per axis; ``slices``: every rank's mesh particles (:mod:`parmpm.driver.mesh_slices`), which
    every rank counts at the patch sizes the advice tries (then collective: every rank holds
    the same ``counts``, so all try the same sizes)."""
    rank = comm.Get_rank()
    slices = slices or None  # no mesh body: rank 0's advice alone
    if comm.Get_size() == 1 or (rank != 0 and slices is None):
        return

    def count_at(size: int):
        other = D.with_patch_size(size)
        lay = other.layout
        if slices is not None:
            mine = where.patch_counts(other) if rank == 0 else np.zeros(lay.n_patches, np.int64)
            return lay, mine + slices.patch_counts(comm, other)
        if not isinstance(where, np.ndarray):
            return lay, where.patch_counts(other)
        at = np.zeros(where.shape[0], np.int64)
        locate_patches(D.dim, where, other.origin3, other.inv_h3, lay.cells3, lay.psize3,
                       lay.patches_per_axis, at, at)
        return lay, np.bincount(at, minlength=lay.n_patches)

    line = idle_ranks_warning(D.layout, counts, comm.Get_size(), D.dim, count_at)
    if line is not None and rank == 0:
        logger.warning(line)
