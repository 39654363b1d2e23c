"""Filling numba's cache: the kernels a run uses, compiled once and loaded by every later run.

Every kernel is ``@njit(cache=True)`` (:mod:`parmpm.core.jit`): the first run of a dimension and
interpolator compiles for 20–40 s, later runs load the machine code from numba's cache in well
under a second. Three things here deal with that first run:

* :func:`compile_notice`: one info line as soon as numba starts compiling a cached kernel that is
  not in its cache (numba's own ``numba:compile`` event, fired only on a cache miss, so the line
  is never printed for a run that merely loads), naming the cache folder; with ``-v`` every
  compiled kernel and its time at DEBUG.
* :func:`compile_kernels` (``parmpm compile``): one tiny run of each dimension × interpolator ×
  USL/MUSL × transfer the interpolator takes (FLIP; for ``bspline`` also APIC and MLS,
  :mod:`parmpm.transfer.affine`), in-process, two steps each, with everything a run switches on around the step
  (damage and CPDI freeze, fixed and slip regions, gravity, metrics with the separation count,
  history with probes, snapshots with domains), a step at a fixed ``time.dt`` (G2P's kernels
  without the wave speed), then what a rank of a multi-rank run does that
  one rank alone does not: the separation count's shared pairs, a patch-set change, and a step
  with no patch and no particle (the idle ranks of a run on more ranks than occupied patches).
  A batch job runs it once before ``srun``; a run on any number of ranks then compiles nothing.
* :func:`compile_first`: under MPI, the scene's own kernels are compiled before the run, split
  between two ranks while the others wait, so that P ranks do not compile the same kernels P
  times at once (on an oversubscribed node that multiplies the start-up). Rank 0 runs the scene
  itself for two steps on its own (its outputs first, then its steps) while rank 1 takes the two
  steps alone (its step's kernels first): two cores compile at once, and only what this scene
  uses (a tiny run of everything a step can switch on compiled, for the default scene, 24
  kernels in 59 s where the scene needs 17 in 36 s). A scene past
  :data:`SCENE_WARM_UP_PARTICLES` would cost rank 0 its whole set-up: it gets the tiny run of
  its dimension, method, update and transfer instead. The other ranks wait in a polled,
  non-blocking barrier: MPICH's blocking one spins and would take the cores the two compile on.
  With a warm cache this costs the two ranks a set-up of the small scene and two steps.

Not covered by the tiny runs (compiled by the run that needs them): the manufactured solution's
body force.
"""
from __future__ import annotations

import contextlib
import copy
import logging
import shutil
import tempfile
import time

from parmpm.materials import PLASTIC_MODELS
from parmpm.transfer.affine import AFFINE_TRANSFERS, APIC_INTERPOLATORS, TRANSFERS
from parmpm.core.log import get_logger
from parmpm.scene.schema import UPDATES
from parmpm.shapes import INTERPOLATORS

log = get_logger(__name__)

DIMS = (1, 2, 3)
#: the tiny plastic run's (dim, method, update) (:func:`compile_kernels`, :func:`compile_first`)
PLASTIC_CASE = (2, "cpdi", "usl")
METHODS = tuple(INTERPOLATORS)
#: the updates a tiny run is made for: "auto" is one of these two
COMPILED_UPDATES = ("usl", "musl")
#: the cache is keyed to the sources (:mod:`parmpm.core.cache_key`): the first run after any edit or
#: upgrade compiles too
NOTICE = ("compiling kernels (first run of these sources: half a minute to a minute; cached "
          "afterwards in {where})")


# --- the notice ---------------------------------------------------------------------------------
def _name(dispatcher) -> str:
    fn = dispatcher.py_func
    return f"{fn.__module__}.{fn.__qualname__}"


def _cached(dispatcher) -> bool:
    """Whether ``dispatcher`` keeps its machine code in numba's on-disk cache."""
    return type(getattr(dispatcher, "_cache", None)).__name__ not in ("NullCache", "NoneType")


class CompileNotice:
    """A numba event listener: the first cache miss of a cached kernel logs :data:`NOTICE`;
    every top-level compilation is timed (``seconds``, ``kernels``) and logged at DEBUG."""

    def __init__(self):
        from numba.core import event

        class _Listener(event.Listener):
            def on_start(inner, ev):  # noqa: N805 (the outer self is the state)
                self._start(ev.data["dispatcher"])

            def on_end(inner, ev):  # noqa: N805
                self._end(ev.data["dispatcher"])

        self.listener = _Listener()
        self.announced = False
        self.seconds, self.kernels = 0.0, 0
        self._stack: list[float] = []

    def _start(self, dispatcher) -> None:
        self._stack.append(time.perf_counter())
        if not self.announced and _cached(dispatcher):
            self.announced = True
            where = getattr(dispatcher._cache, "_cache_path", "numba's cache folder")
            log.info(NOTICE.format(where=where))

    def _end(self, dispatcher) -> None:
        if not self._stack:
            return
        took = time.perf_counter() - self._stack.pop()
        if not self._stack:  # a kernel compiled for its own sake, not inside another's compile
            self.seconds += took
            self.kernels += 1
            log.debug("compiled %s in %.2f s", _name(dispatcher), took)


@contextlib.contextmanager
def compile_notice():
    """Listen for numba's compilations while the block runs; yields the :class:`CompileNotice`."""
    from numba.core import event

    notice = CompileNotice()
    with event.install_listener("numba:compile", notice.listener):
        yield notice


# --- tiny runs ----------------------------------------------------------------------------------
def _vec(values) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def transfers_of(method: str) -> tuple[str, ...]:
    """The transfers ``method`` can run with: FLIP always, APIC and MLS with the B-spline."""
    return TRANSFERS if method in APIC_INTERPOLATORS else ("flip",)


#: the tiny scene's materials: elastic (one with damage) ...
_ELASTIC = """\
[materials.solid]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
[materials.solid.damage]
onset = 5.0
fracture = 6.0
[materials.soft]
model = "linear_elastic"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.2
"""
#: ... or plastic (the plastic pass and its sums: one compilation serves every dimension and
#: interpolator)
_PLASTIC = """\
[materials.solid]
model = "j2"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
yield_stress = 1.0e-3
[materials.soft]
model = "drucker_prager"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.2
friction_angle = 30.0
cohesion = 0.0
"""
#: the tiny scene of :func:`tiny_scene_toml`, filled in per case
_TINY_SCENE = """\
name = "compile_{dim}d_{method}_{update}_{transfer}"
dim = {dim}
[grid]
origin = {origin}
cell_size = 0.1
cells = {cells}
patch_size = 4
{materials}[[bodies]]
min = {lo_a}
max = {hi_a}
material = "solid"
velocity = {velocity}
[[bodies]]
min = {lo_b}
max = {hi_b}
material = "soft"
[method]
interpolator = "{method}"
update = "{update}"
{lcr}[gravity]
g = {g}
[boundary]
{faces}{regions}[time]
steps = 2
[output]
every_steps = 1
figure = false
[[output.history.probes]]
name = "point"
point = {probe}
fields = ["u.x", "stress.xx", "J"]
[[output.history.probes]]
name = "body"
body = 0
fields = ["v.x", "damage"]
stats = ["mean", "max"]
[metrics]
kind = "{metrics}"
"""


def tiny_scene_toml(dim: int, method: str, update: str, transfer: str = "flip",
                    plastic: bool = False) -> str:
    """A scene of a few hundred particles that takes every path of a step around the kernels:
    a damageable neo-Hookean block (damage never starts, but the CPDI freeze check runs) and a
    linear-elastic one, moving fast enough to cross a patch face, under gravity, between a fixed
    and a slip face (and a symmetry face in 2D and 3D), with a fixed and a slip region, hanging-bar metrics (the separation count),
    a history with probes and snapshots with domains. ``plastic``: the two blocks J2 and
    Drucker–Prager instead (yielding at once)."""
    if (dim not in DIMS or method not in METHODS or update not in UPDATES
            or transfer not in transfers_of(method)):
        raise ValueError(f"tiny scene: dim {dim}, method {method!r}, update {update!r}, "
                         f"transfer {transfer!r}")
    zeros, cells = [0.0] * dim, [10] * dim
    lo_a, hi_a = [0.2] * dim, [0.5] * dim
    lo_b, hi_b = [0.2] * (dim - 1) + [0.6], [0.5] * (dim - 1) + [0.8]
    velocity = [200.0] + [0.0] * (dim - 1)
    g = [0.0] * (dim - 1) + [-10.0]
    faces = "x_min = \"fixed\"\n" + ("y_min = \"slip\"\ny_max = \"symmetry\"\n" if dim > 1
                                      else "x_max = \"slip\"\n")
    lcr = "" if method in ("cpdi", "cpdi2") else 'lcr = "none"\n'
    regions = "" if method == "bspline" else (  # refused with B-splines (parmpm.scene.schema)
        f"fixed_regions = [{{ min = {_vec([0.0] * dim)}, max = {_vec([0.1] * dim)} }}]\n"
        f"slip_regions = [{{ min = {_vec([0.85] * dim)}, max = {_vec([0.95] * dim)}, "
        'normal = "x" }]\n')
    if transfer in AFFINE_TRANSFERS:
        lcr += f'transfer = "{transfer}"\n'
    return _TINY_SCENE.format(
        materials=_PLASTIC if plastic else _ELASTIC, metrics="none" if plastic else "hanging_bar",
        dim=dim, method=method, update=update, transfer=transfer, lcr=lcr, faces=faces,
        regions=regions,
        origin=_vec(zeros), cells=_vec(cells), lo_a=_vec(lo_a), hi_a=_vec(hi_a),
        velocity=_vec(velocity), lo_b=_vec(lo_b), hi_b=_vec(hi_b), g=_vec(g),
        probe=_vec([0.3] * dim))


@contextlib.contextmanager
def _only_compile_messages(level: int = logging.WARNING):
    """The tiny run's own info lines (folders, patch sizes) are noise here (below ``level``);
    the notice is not."""
    root, own = logging.getLogger("parmpm"), logging.getLogger(log.name)
    saved = root.level, own.level
    own.setLevel(root.getEffectiveLevel())
    root.setLevel(max(root.level, level))
    try:
        yield
    finally:
        root.setLevel(saved[0])
        own.setLevel(saved[1])


def _claims_two_ranks():
    """One rank that says there are two: the separation count then takes its multi-rank path
    (pairs shared with other ranks, merged on rank 0) and compiles its kernels too."""
    from decomposition import SerialComm

    class ClaimsTwoRanks(SerialComm):
        def Get_size(self) -> int:
            return 2

    return ClaimsTwoRanks()


def warm_up(dim: int, method: str, update: str, transfer: str = "flip",
            plastic: bool = False) -> float:
    """Run the tiny scene of (dim, method, update, transfer), elastic or ``plastic``, on this
    process alone (two steps, output in a temporary folder, removed); returns its wall time in
    seconds."""
    from decomposition import SerialComm
    from parmpm.driver.measures import components
    from parmpm.scene.load import scene_from_toml
    from parmpm.driver.simulation import Simulation

    scene = scene_from_toml(tiny_scene_toml(dim, method, update, transfer, plastic),
                            f"compile-{dim}d-{method}")
    tmp = tempfile.mkdtemp(prefix="parmpm-compile-")
    t0 = time.perf_counter()
    try:
        with _only_compile_messages():
            sim = Simulation(scene, tmp, quiet=True, comm=SerialComm())
            sim.state.stepper.compile_lazy_order()
            sim.run()
            sim.domain_corners()  # the figure's (2D; the tiny run draws none)
            sim.state.comm = _claims_two_ranks()
            components(sim.state)
            sim.state.comm = SerialComm()
            _patch_set_change(sim)
            _fixed_step(sim)
            _idle_rank_step(sim)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return time.perf_counter() - t0


def _regroup(sim) -> None:
    """What a run does when particles change patch (their order merged, :mod:`parmpm.particles.
    order`) and when its patch set changes (:func:`_patch_set_change`): two steps of a small scene
    seldom do either. Last: it leaves the particles in a lazy order."""
    P, ps = sim.particles, sim.state.patches
    P.group_by_patch(P.rows.patch.copy(), ps.slot_of, ps.n_local, moved=1)
    _patch_set_change(sim)


def _patch_set_change(sim) -> None:
    """What a rank does when its patches change but its particles stay (a patch became occupied
    or empty, or a re-balance moved other ranks' patches): the particles' runs move to their
    new slots (:meth:`parmpm.particles.store.Particles.group_by_patch`). The tiny grid's patches are
    all active from the start, so its run never changes them."""
    P, ps = sim.particles, sim.state.patches
    P.group_by_patch(P.rows.patch, ps.slot_of, ps.n_local, force=True)


def _fixed_step(sim) -> None:
    """A step as a run with a fixed step (``time.dt``) takes it: G2P's kernels without the wave
    speed (:meth:`parmpm.step.stepper.Stepper.fix_step`), for a lazy particle order and (the
    rows just regrouped) the canonical one. The tiny run's own steps are the CFL ones."""
    st = sim.state.stepper
    st.fix_step()
    st.compile_lazy_order()
    st.step(sim.state.clock.last_dt or 1e-6, sim.gravity(sim.t), sim.t)


def _idle_rank_step(sim) -> None:
    """One step as a rank without work takes it (more ranks than patches holding particles): no
    particle and no patch, so every array it hands the kernels is empty. numba types an empty
    array as contiguous where a working rank's node-major grid views are strided: P2G, G2P and
    the halo copies of other types, which every idle rank once compiled at its first step (the
    stepper now gives such a rank views of spare slots; this step keeps anything else an idle
    rank would compile in the cache too), with the CFL step and (after :func:`_fixed_step`) a
    fixed one. Last: it empties the tiny run."""
    import numpy as np

    st, ps = sim.state.stepper, sim.state.patches
    sim.particles.permute(np.zeros(0, np.int64))
    ps.update(np.zeros(sim.state.disc.layout.n_patches, np.int64))  # nothing occupied: no patch
    st.patches_changed()
    dt = sim.state.clock.last_dt or 1e-6
    st.step(dt, sim.gravity(sim.t), sim.t)
    if st.speed_watch is not None:
        st.transfers.cfl = True
        st.step(dt, sim.gravity(sim.t), sim.t)


def compile_kernels(dims=DIMS, methods=METHODS, updates=COMPILED_UPDATES,
                    transfers=TRANSFERS) -> list[dict]:
    """Fill numba's cache for every (dim, method, update, transfer) given (the transfers a
    method does not take are skipped); one row per case (seconds, kernels compiled: 0 when all
    came from the cache)."""
    rows = []
    with compile_notice() as notice:
        for dim in dims:
            for method in methods:
                for update in updates:
                    for transfer in (t for t in transfers if t in transfers_of(method)):
                        before = notice.kernels
                        seconds = warm_up(dim, method, update, transfer)
                        rows.append({"dim": dim, "method": method, "update": update,
                                     "transfer": transfer, "seconds": seconds,
                                     "compiled": notice.kernels - before})
                        log.info("%dD %-7s %-4s %-4s  %5.1f s  %s", dim, method, update,
                                 transfer, seconds,
                                 f"{rows[-1]['compiled']} kernels compiled"
                                 if rows[-1]["compiled"] else "all cached")
        if PLASTIC_CASE[0] in dims and PLASTIC_CASE[1] in methods:
            # the plastic pass and its sums: one compilation serves every dimension and method
            before = notice.kernels
            seconds = warm_up(*PLASTIC_CASE, plastic=True)
            rows.append({"dim": PLASTIC_CASE[0], "method": PLASTIC_CASE[1],
                         "update": PLASTIC_CASE[2], "transfer": "flip", "plastic": True,
                         "seconds": seconds, "compiled": notice.kernels - before})
            log.info("plastic materials  %5.1f s  %s", seconds,
                     f"{rows[-1]['compiled']} kernels compiled" if rows[-1]["compiled"]
                     else "all cached")
    return rows


# --- rank 0 first -------------------------------------------------------------------------------
#: (dim, method, update, transfer) warmed up in this process already: staged once, then never
#: again
_WARMED: set = set()


def wait_for_all(comm, poll: float = 0.01) -> None:
    """A barrier that sleeps while it waits (``Ibarrier`` polled): a blocking MPI barrier spins
    on its core, which a compiling rank on the same node needs."""
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(poll)


def compile_first(scene, comm) -> None:
    """Collective: compile (or load) the scene's kernels before its run, on rank 0 and rank 1 at
    once while the other ranks wait (the module doc says how); then every rank loads them from the
    cache. Once per process and scene (or case); a failed warm-up is only a debug message (the
    run then compiles as before)."""
    spec = scene.spec
    if comm is None or comm.Get_size() == 1:
        return
    # (what, plastic): the scene itself (its text), or a tiny run's case
    if particles_estimate(spec) <= SCENE_WARM_UP_PARTICLES:
        cases = [(("scene", scene.to_toml()), False)]
    else:
        m = spec.method
        plastic = any(mat.model in PLASTIC_MODELS for mat in spec.materials.values())
        cases = [c for c in (((spec.dim, m.interpolator, m.update, m.transfer), False),
                             (PLASTIC_CASE + ("flip",), True)) if c[1] <= plastic]
    cases = [c for c in cases if c not in _WARMED]
    if not cases:
        return
    _WARMED.update(cases)
    rank = comm.Get_rank()
    try:
        if rank <= 1:
            try:
                t0 = time.perf_counter()
                for case, plastic in cases:
                    if case[0] == "scene":
                        scene_warm_up(scene, outputs=rank == 0)
                    elif rank == 0:
                        warm_up(*case, plastic=plastic)
                log.debug("rank %d warmed up the kernels in %.1f s", rank,
                          time.perf_counter() - t0)
            except Exception as exc:  # the run itself will meet (and report) any real problem
                log.debug("kernel warm-up failed (%s: %s); every rank compiles",
                          type(exc).__name__, exc)
    finally:
        wait_for_all(comm)


def particles_estimate(spec) -> float:
    """:func:`parmpm.driver.footprint.particles_estimate`, imported when called: it loads the
    kernels' modules, which ``parmpm --help`` and the CLI's parser must not."""
    from parmpm.driver.footprint import particles_estimate as estimate

    return estimate(spec)


#: the most particles (:func:`parmpm.driver.footprint.particles_estimate`) a scene may have for
#: rank 0 to warm up with the scene itself (:func:`compile_first`); the default scene has 900
SCENE_WARM_UP_PARTICLES = 20_000


def scene_warm_up(scene, outputs: bool = True) -> float:
    """The scene itself, two steps on this process alone (output in a temporary folder,
    removed): with ``outputs`` a run (the initial outputs, then the steps, then the final
    ones, as the scene asks for them), else only the two steps. Returns its wall time; warnings
    of the scene (the run repeats them) and its info lines are not shown."""
    from decomposition import SerialComm
    from parmpm.driver.measures import components
    from parmpm.driver.simulation import Simulation
    from parmpm.output.metrics import separation_kinds
    from parmpm.scene.load import Scene

    data = copy.deepcopy(scene.data)  # resolved: its files are not read again
    data["time"]["steps"] = 2
    data["output"]["figure"] = False
    small = Scene(data, scene.source)
    tmp = tempfile.mkdtemp(prefix="parmpm-compile-")
    t0 = time.perf_counter()
    try:
        with _only_compile_messages(level=logging.CRITICAL):
            sim = Simulation(small, tmp, quiet=True, comm=SerialComm())
            if outputs:
                sim.run()
                if small.spec.metrics.kind in separation_kinds():  # its multi-rank path too
                    sim.state.comm = _claims_two_ranks()
                    components(sim.state)
            else:
                clock, stepper = sim.state.clock, sim.state.stepper
                while not clock.done():
                    dt = clock.next_dt()
                    vmax = stepper.step(dt, sim.gravity(clock.t), clock.t)
                    clock.tick(dt, vmax, stepper.speed_measured)
                _regroup(sim)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return time.perf_counter() - t0
