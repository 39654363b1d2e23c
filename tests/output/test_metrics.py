"""Separation counting and scene metrics on synthetic particle states."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from parmpm.output.connectivity import local_components
from parmpm.core.errors import SceneError
from parmpm.exact.bars import (hanging_bar_static_displacement, nominal_stress_1d,
                          vibrating_bar_com_velocity)
from parmpm.output.metrics import HangingBarMetrics, VibratingBarMetrics, count_components, make_metrics

# the component count of the union-find kernel, compiled and through its pure-Python body
KERNELS = [pytest.param(lambda *a: local_components(*a)[0], id="jit"),
           pytest.param(lambda *a: local_components.py_func(*a)[0], id="py")]


def _bfs_components(nodes, nnodes):
    """Reference: breadth-first search on the particle graph (particles sharing a node)."""
    n = nodes.shape[0]
    by_node = {}
    for p in range(n):
        for k in range(nnodes[p]):
            by_node.setdefault(int(nodes[p, k]), []).append(p)
    seen = np.zeros(n, bool)
    count = 0
    for s in range(n):
        if seen[s]:
            continue
        count += 1
        stack = [s]
        seen[s] = True
        while stack:
            p = stack.pop()
            for k in range(nnodes[p]):
                for q in by_node[int(nodes[p, k])]:
                    if not seen[q]:
                        seen[q] = True
                        stack.append(q)
    return count


def _chain_1d(cells_with_particles, n_cells):
    """1D linear-hat particles, one per listed cell: nodes (c, c+1)."""
    c = np.asarray(cells_with_particles, dtype=np.int64)
    nodes = np.stack([c, c + 1], axis=1)
    return nodes, np.full(c.size, 2, dtype=np.int64), n_cells + 1


@pytest.mark.parametrize("kernel", KERNELS)
def test_components_chain_and_gap(kernel):
    nodes, nn, n_nodes = _chain_1d([0, 1, 2, 3], 10)
    assert kernel(nodes, nn, n_nodes) == 1
    # an empty cell between cells 1 and 3 leaves node 2 shared by cells 1 and 2 only
    nodes, nn, n_nodes = _chain_1d([0, 1, 3, 4], 10)
    assert kernel(nodes, nn, n_nodes) == 2  # cells 1 and 3 share no node
    nodes, nn, n_nodes = _chain_1d([0, 0, 5, 8], 10)
    assert kernel(nodes, nn, n_nodes) == 3


@pytest.mark.parametrize("kernel", KERNELS)
def test_components_padding_and_isolated(kernel):
    nodes = np.array([[0, 1, 99], [1, 2, 99], [5, 6, 7], [0, 0, 0]], dtype=np.int64)
    nn = np.array([2, 2, 3, 0], dtype=np.int64)  # 99 is padding, particle 3 touches nothing
    assert kernel(nodes, nn, 100) == 3


@pytest.mark.parametrize("kernel", KERNELS)
def test_components_random_against_bfs(kernel):
    rng = np.random.default_rng(7)
    for _ in range(20):
        n, K, n_nodes = 60, 4, 150
        nodes = rng.integers(0, n_nodes, size=(n, K)).astype(np.int64)
        nn = rng.integers(0, K + 1, size=n).astype(np.int64)
        expected = _bfs_components(nodes, nn)
        assert kernel(nodes, nn, n_nodes) == expected
        perm = rng.permutation(n)
        assert kernel(nodes[perm].copy(), nn[perm].copy(), n_nodes) == expected


def test_count_components_wrapper():
    assert count_components(np.zeros((0, 4), np.int64), np.zeros(0, np.int64), 10) == 0
    # huge id space: compressed before the kernel, same answer
    big = 10**12
    nodes = np.array([[big - 1, 5], [5, 7], [3 * 10**9, 4 * 10**9]], dtype=np.int64)
    nn = np.array([2, 2, 2])
    assert count_components(nodes, nn, big) == 2
    # int32 input, 2D grid: two blocks of linear-hat particles separated by an empty column
    nx = 10
    nodes2, nn2 = [], []
    for i in list(range(0, 3)) + list(range(5, 8)):
        for j in range(3):
            nodes2.append([i + (nx + 1) * j, i + 1 + (nx + 1) * j, i + (nx + 1) * (j + 1), i + 1 + (nx + 1) * (j + 1)])
            nn2.append(4)
    assert count_components(np.array(nodes2, np.int32), np.array(nn2, np.int32), (nx + 1) * 5) == 2
    with pytest.raises(ValueError):
        count_components(np.zeros((2, 2), np.int64), np.array([3, 1]), 4)
    with pytest.raises(ValueError, match="negative"):
        count_components(np.array([[0, -1], [1, 2]]), np.array([2, 2]), 4)
    # a negative id in the padding is not read
    assert count_components(np.array([[0, -1], [1, 2]]), np.array([1, 2]), 4) == 2


def _bfs_labels(nodes, nnodes):
    """Reference labels: breadth-first search from each unlabelled particle in index order, so
    a piece's label is its place in the order of its first particle."""
    n = nodes.shape[0]
    by_node = {}
    for p in range(n):
        for k in range(nnodes[p]):
            by_node.setdefault(int(nodes[p, k]), []).append(p)
    label = np.full(n, -1, np.int64)
    k = 0
    for s in range(n):
        if label[s] >= 0:
            continue
        label[s] = k
        stack = [s]
        while stack:
            p = stack.pop()
            for e in range(nnodes[p]):
                for q in by_node[int(nodes[p, e])]:
                    if label[q] < 0:
                        label[q] = k
                        stack.append(q)
        k += 1
    return k, label


@pytest.mark.parametrize("ids", ["small", "lattice", "huge"])
def test_labels_are_the_pieces_in_order_of_their_first_particle(ids):
    """The labels (which ``shared_pairs`` sends to the other ranks) against breadth-first search,
    with the table sized to exactly the distinct ids: ids in a small range, ids on a lattice's
    stride (the low bits alike: global ids of a 3D grid's column), and ids near 2^62."""
    rng = np.random.default_rng(11)
    for trial in range(30):
        n, K = int(rng.integers(1, 80)), int(rng.integers(1, 9))
        raw = rng.integers(0, 3 * n, size=(n, K))
        nodes = {"small": raw, "lattice": raw * 4096 + 7, "huge": 2**62 - 1 - raw * 2**40}[ids]
        nodes = nodes.astype(np.int64)
        nn = rng.integers(0, K + 1, size=n).astype(np.int64)
        valid = np.arange(K)[None, :] < nn[:, None]
        distinct = max(1, np.unique(nodes[valid]).size)
        k, label = local_components(nodes, nn, distinct)
        k_ref, label_ref = _bfs_labels(nodes, nn)
        assert k == k_ref
        np.testing.assert_array_equal(label, label_ref)


# --------------------------------------------------------------------------------------------
def _spec(scene):
    """A hand-made resolved-scene dict read as its records are (``scene.spec``,
    :mod:`parmpm.scene.records`): tables as attributes, lists as tuples, materials by name."""
    if isinstance(scene, list):
        return tuple(_spec(v) for v in scene)
    if not isinstance(scene, dict):
        return scene
    fields = {k: _spec(v) for k, v in scene.items() if k != "materials"}
    if "materials" in scene:
        fields["materials"] = {n: _spec(m) for n, m in scene["materials"].items()}
    return SimpleNamespace(**fields)


def _scene_1d(L=1.0, n=32, E=1e6, nu=0.0, rho=1050.0, g=1000.0, model="neo_hookean"):
    # the resolved-scene layout of parmpm.scene.schema
    scene = {
        "dim": 1,
        "materials": {"rubber": {"model": model, "density": rho, "youngs_modulus": E, "poisson_ratio": nu}},
        "bodies": [{"shape": "box", "min": [0.0], "max": [L], "material": "rubber", "vibration": None}],
        "gravity": {"g": [-g], "ramp_time": 0.0},
        "metrics": {"kind": "hanging_bar", "every_steps": 10, "axis": 0},
    }
    h = L / n
    x0 = (np.arange(n) + 0.5)[:, None] * h
    mass = np.full(n, rho * h)
    return scene, x0, mass


def test_hanging_bar_1d_exact_static_state():
    scene, x0, mass = _scene_1d()
    m = make_metrics(_spec(scene), x0, mass)
    assert isinstance(m, HangingBarMetrics)
    L = 1.0
    law = nominal_stress_1d("neo_hookean", 1e6, 0.0)
    X = L - x0[:, 0]  # distance from the support at the top
    u = hanging_bar_static_displacement(X, L, 1050.0, 1000.0, law)  # downward displacement
    s = 1050.0 * 1000.0 / 1e6 * (L - X)
    lam = s + np.sqrt(1 + s * s)
    x = (x0[:, 0] - u)[:, None]
    F = lam[:, None, None]
    v = np.zeros_like(x)
    m.sample(0.0, x0, v, np.ones_like(F), 1)
    m.sample(1.0, x, v, F, 1)
    r = m.result()
    json.dumps(r, allow_nan=False)
    assert r["exact_static_elongation"] == pytest.approx(0.6863289199400745, rel=1e-12)
    assert r["tip_displacement"] < 0
    assert r["relative_error_static"] < 1e-9
    # the tip particle sits half a spacing above the free end: its exact u is a bit below dL
    assert r["exact_static_tip_displacement"] < r["exact_static_elongation"]
    assert r["max_stretch"] == pytest.approx(lam.max())
    assert r["separated"] is False and r["separation_time"] is None
    assert r["stretch_at_separation"] is None and r["samples"] == 2
    assert r["max_tip_displacement"] == pytest.approx(abs(r["tip_displacement"]))


def test_hanging_bar_1d_linear_law():
    scene, x0, mass = _scene_1d(model="linear_elastic", nu=0.25, g=10.0)
    m = HangingBarMetrics(_spec(scene), x0, mass)
    lam_l = 1e6 * 0.25 / (1.25 * 0.5)
    mu = 1e6 / 2.5
    k = 1050.0 * 10.0 / (lam_l + 2 * mu)
    assert m.exact_static_elongation == pytest.approx(k / 2, rel=1e-10)


def test_hanging_bar_2d_separation():
    L, W, n = 1.0, 0.2, 20
    scene = {
        "dim": 2,
        "materials": {"rubber": {"model": "neo_hookean", "density": 1050.0, "youngs_modulus": 1e6,
                                 "poisson_ratio": 0.3}},
        "bodies": [{"shape": "box", "min": [0.0, -L], "max": [W, 0.0], "material": "rubber",
                    "vibration": None}],
        "gravity": {"g": [0.0, -1000.0], "ramp_time": 0.0},
        "metrics": {"kind": "hanging_bar", "every_steps": 1, "axis": 1},
    }
    xs, ys = np.meshgrid((np.arange(4) + 0.5) * W / 4, -L + (np.arange(n) + 0.5) * L / n, indexing="ij")
    x0 = np.stack([xs.ravel(), ys.ravel()], axis=1)
    mass = np.ones(x0.shape[0])
    m = make_metrics(_spec(scene), x0, mass)
    assert m.axis == 1 and m.tip.size == 4
    F = np.tile(np.eye(2), (x0.shape[0], 1, 1))
    v = np.zeros_like(x0)
    stretches = [1.5, 3.0, 4.5, 2.0]
    for i, (t, s) in enumerate(zip([0.1, 0.2, 0.3, 0.4], stretches)):
        Fi = F.copy()
        Fi[:, 0, 1] = 0.1  # shear does not count, F e_y = (0.1, s)
        Fi[0, 1, 1] = s
        x = x0.copy()
        x[m.tip, 1] -= 0.1 * (i + 1)
        m.sample(t, x, v, Fi, 1 if i < 2 else 2)
    r = m.result()
    json.dumps(r, allow_nan=False)
    assert r["separated"] is True
    assert r["separation_time"] == pytest.approx(0.3)
    assert r["stretch_at_separation"] == pytest.approx(math.hypot(0.1, 4.5))
    assert r["max_stretch"] == pytest.approx(math.hypot(0.1, 4.5))
    assert r["tip_displacement"] == pytest.approx(-0.4)
    assert r["max_tip_displacement"] == pytest.approx(0.4)
    assert r["exact_static_elongation"] is None and r["relative_error_static"] is None
    assert r["max_components"] == 2


def test_hanging_bar_gravity_along_plus_axis():
    scene, x0, mass = _scene_1d()
    scene["gravity"]["g"] = [1000.0]
    m = HangingBarMetrics(_spec(scene), x0, mass)
    assert m.tip.tolist() == [x0.shape[0] - 1]  # lowest = largest coordinate
    x = x0.copy()
    x[-1, 0] += 0.2  # moves along gravity: downward
    m.sample(0.0, x, np.zeros_like(x), np.ones((x0.shape[0], 1, 1)), None)
    assert m.result()["tip_displacement"] == pytest.approx(-0.2)
    assert m.result()["separated"] is False


def _vib_scene(dim=1, nu=0.0, n=200):
    E, rho, L, v0 = 100.0, 1.0, 25.0, 0.1
    lo, hi = [0.0] * dim, [L] + [1.0] * (dim - 1)
    scene = {
        "dim": dim,
        "materials": {"m": {"model": "linear_elastic", "density": rho, "youngs_modulus": E, "poisson_ratio": nu}},
        "bodies": [{"shape": "box", "min": lo, "max": hi, "material": "m",
                    "vibration": {"amplitude": v0, "mode": 1, "axis": 0}}],
        "gravity": {"g": [0.0] * dim, "ramp_time": 0.0},
        "metrics": {"kind": "vibrating_bar", "every_steps": 5, "axis": 0},
    }
    X = (np.arange(n) + 0.5) * L / n
    x0 = np.zeros((n, dim))
    x0[:, 0] = X
    if dim > 1:
        x0[:, 1] = 0.5
    return scene, x0, np.full(n, rho * L / n), (E, rho, L, v0)


@pytest.mark.parametrize("scale, expected", [(1.0, 0.0), (1.02, 0.02)])
def test_vibrating_bar_metric(scale, expected):
    scene, x0, mass, (E, rho, L, v0) = _vib_scene()
    m = make_metrics(_spec(scene), x0, mass)
    assert isinstance(m, VibratingBarMetrics)
    assert m.period == pytest.approx(10.0)
    beta = math.pi / (2 * L)
    omega = math.sqrt(E / rho) * beta
    for t in np.linspace(0.0, 20.0, 41):
        v = np.zeros_like(x0)
        v[:, 0] = scale * v0 * math.cos(omega * t) * np.sin(beta * x0[:, 0])
        m.sample(t, x0, v, np.ones((x0.shape[0], 1, 1)), 1)
    r = m.result()
    json.dumps(r, allow_nan=False)
    assert r["samples"] == 41 and r["period"] == pytest.approx(10.0)
    # midpoint rule over 200 particles: O(h^2) ~ 1e-5 error in the mean
    assert r["com_velocity_rel_l2_error"] == pytest.approx(expected, abs=5e-5)
    np.testing.assert_allclose(m.com_velocity_exact, vibrating_bar_com_velocity(m.times, v0, L, E, rho))


def test_vibrating_bar_wave_modulus_by_dimension():
    E, nu = 100.0, 0.3
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    for dim, modulus in [(1, lam + 2 * mu), (2, E / (1 - nu**2)), (3, E)]:
        scene, x0, mass, _ = _vib_scene(dim=dim, nu=nu, n=20)
        m = make_metrics(_spec(scene), x0, mass)
        assert m.modulus == pytest.approx(modulus)
        assert m.L == pytest.approx(25.0)


def test_make_metrics_kinds():
    scene, x0, mass = _scene_1d()
    scene["metrics"]["kind"] = "none"
    assert make_metrics(_spec(scene), x0, mass) is None
    scene["metrics"] = {"kind": "teapot"}
    with pytest.raises(SceneError):
        make_metrics(_spec(scene), x0, mass)
    scene["metrics"] = {"kind": "vibrating_bar"}
    with pytest.raises(SceneError):  # body 0 has no vibration table
        make_metrics(_spec(scene), x0, mass)


def test_lattice_fallback_without_box():
    """A disk has no box: the bar's span is that of its particle lattice."""
    scene = {
        "dim": 2,
        "materials": {"rubber": {"model": "neo_hookean", "density": 1050.0, "youngs_modulus": 1e6,
                                 "poisson_ratio": 0.0}},
        "bodies": [{"shape": "disk", "center": [0.5, 0.5], "radius": 0.5, "material": "rubber",
                    "vibration": None}],
        "gravity": {"g": [0.0, -1000.0], "ramp_time": 0.0},
        "metrics": {"kind": "hanging_bar", "every_steps": 1, "axis": 1},
    }
    c = (np.arange(16) + 0.5) / 16
    x0 = np.stack(np.meshgrid(c, c, indexing="ij"), axis=-1).reshape(-1, 2)
    x0 = x0[np.sum((x0 - 0.5) ** 2, axis=1) <= 0.25]
    m = HangingBarMetrics(_spec(scene), x0, np.ones(x0.shape[0]))
    assert m.L == pytest.approx(1.0)
    assert m.X_tip == pytest.approx(1.0 - 0.5 / 16)


def test_metrics_read_only_the_resolved_scene():
    """Every built-in scene with metrics builds them from its resolved form."""
    import parmpm

    for name in parmpm.builtin_scenes():
        spec = parmpm.load_scene(name).spec
        kind = spec.metrics.kind
        if kind not in ("hanging_bar", "vibrating_bar"):
            continue
        lo = np.asarray(spec.bodies[0].min)
        hi = np.asarray(spec.bodies[0].max)
        x0 = lo + (hi - lo) * np.array([[0.25] * spec.dim, [0.75] * spec.dim])
        m = make_metrics(spec, x0, np.ones(2))
        assert m.kind == kind and m.axis == (
            spec.bodies[0].vibration.axis if kind == "vibrating_bar" else spec.metrics.axis)


# --------------------------------------------------------------------------------------------
# built from each rank's own particles: the same metric as from every particle, bit for bit


class _ThreadComm:
    """A communicator for ranks run as threads of one process: what the metrics' set-up uses
    (rank, size, ``allgather``, ``Allreduce`` with MAX)."""

    def __init__(self, rank, size, shared):
        self.rank, self.size, self.shared = rank, size, shared

    def Get_rank(self):
        return self.rank

    def Get_size(self):
        return self.size

    def allgather(self, obj):
        slots, barrier = self.shared
        slots[self.rank] = obj
        barrier.wait()
        out = list(slots)
        barrier.wait()
        return out

    def Allreduce(self, send, recv, op=None):  # MAX: the only reduction the metrics use
        recv[:] = np.max(np.stack(self.allgather(np.array(send))), axis=0)


def _on_ranks(kind_scene, x0, mass, size, seed=0):
    """The metric built on ``size`` thread-ranks, each holding a random share of the particles
    (in a random order; from 3 ranks on, the last holds none); the metrics of every rank."""
    import threading

    owner = np.random.default_rng(seed).integers(0, size - (size >= 3), x0.shape[0])
    shared = ([None] * size, threading.Barrier(size))
    out, errors = [None] * size, []

    def build(r):
        try:
            gid = np.random.default_rng(r).permutation(np.flatnonzero(owner == r))
            out[r] = make_metrics(_spec(kind_scene), x0[gid], mass[gid], _ThreadComm(r, size, shared), gid)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)
            shared[1].abort()

    threads = [threading.Thread(target=build, args=(r,)) for r in range(size)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    return out


def _disk_scene(kind):
    scene = {
        "dim": 2,
        "materials": {"rubber": {"model": "neo_hookean", "density": 1050.0, "youngs_modulus": 1e6,
                                 "poisson_ratio": 0.0}},
        "bodies": [{"shape": "disk", "center": [0.5, 0.5], "radius": 0.5, "material": "rubber",
                    "vibration": None, "angular_velocity": 2.0}],
        "gravity": {"g": [0.0, -1000.0], "ramp_time": 0.0},
        "metrics": {"kind": kind, "every_steps": 1, "axis": 1},
    }
    if kind == "vibrating_bar":
        scene["bodies"][0]["vibration"] = {"amplitude": 0.1, "mode": 1, "axis": 0}
    c = (np.arange(40) + 0.5) / 40
    x0 = np.stack(np.meshgrid(c, c, indexing="ij"), axis=-1).reshape(-1, 2)
    x0 = x0[np.sum((x0 - 0.5) ** 2, axis=1) <= 0.25]
    return scene, x0, np.full(x0.shape[0], 0.37)


@pytest.mark.parametrize("size", [2, 3, 5])
def test_metrics_built_per_rank_are_the_whole_scenes(size):
    """Tip, corner, span, tip distance, bar mass and rotation radius from each rank's own
    particles and collective reductions equal those from every particle (and no rank keeps a
    particle field)."""
    scene, x0, mass = _scene_1d(n=37)
    scene2, x02, mass2, _ = _vib_scene(dim=2, n=50)
    mass2 = mass2 * (1.0 + 0.1 * (np.arange(50) >= 20))  # two runs of masses
    disk, xd, md = _disk_scene("hanging_bar")
    vib, xv, mv = _disk_scene("vibrating_bar")
    rot, xr, mr = _disk_scene("rotation")
    for data, x, m, keys in ((scene, x0, mass, ("tip", "corner", "L", "X_tip")),
                             (disk, xd, md, ("tip", "corner", "L", "X_tip")),
                             (scene2, x02, mass2, ("L", "bar_mass", "period")),
                             (vib, xv, mv * (1.0 + (xv[:, 0] > 0.5)), ("L", "bar_mass")),
                             (rot, xr, mr, ("stress_scale",))):
        whole = make_metrics(_spec(data), x, m)
        for r, part in enumerate(_on_ranks(data, x, m, size)):
            assert part.x0 is None and part.mass is None
            for k in keys:
                a, b = getattr(whole, k), getattr(part, k)
                assert np.asarray(a).tobytes() == np.asarray(b).tobytes(), (data["metrics"], k, r)


def test_pairwise_runs_is_numpys_sum():
    from parmpm.output.metrics.sums import pairwise_runs

    rng = np.random.default_rng(5)
    for trial in range(200):
        k = int(rng.integers(1, 5))
        counts = rng.integers(1, 400_000 if trial % 25 == 0 else 300, k)
        values = rng.standard_normal(k) * 10.0 ** rng.integers(-4, 4, k)
        assert pairwise_runs(values, counts) == np.sum(np.repeat(values, counts)), (values, counts)
    assert pairwise_runs([], []) == 0.0
    assert str(pairwise_runs([-0.0], [3])) == str(np.sum(np.full(3, -0.0)))


# --- issue 28: a metric's record does not grow with the run -----------------------------------
def _old_first_peak_and_rebound(u, tol=0.01):
    """The whole-history version this module had before issue 28 (the reference)."""
    d = -np.asarray(u, dtype=float)
    high = np.fmax.accumulate(d) if d.size else d
    back = np.flatnonzero((high > 0.0) & (high - d > tol * high))
    if back.size == 0:
        return None, None
    i_peak = int(np.nanargmax(d[: back[0] + 1]))
    rest = d[i_peak:]
    low = np.fmin.accumulate(rest)
    up = np.flatnonzero(rest - low > tol * d[i_peak])
    if up.size == 0:
        return i_peak, None
    return i_peak, i_peak + int(np.nanargmin(rest[: up[0] + 1]))


def test_turning_points_one_sample_at_a_time_match_the_whole_history():
    from parmpm.output.metrics.bars import first_peak_and_rebound

    rng = np.random.default_rng(28)
    for trial in range(400):
        n = int(rng.integers(0, 80))
        t = np.linspace(0.0, 1.0, n)
        u = -(1.0 - np.cos(2 * np.pi * t / rng.uniform(0.1, 1.5))) * rng.uniform(0.5, 2.0)
        u += rng.normal(0.0, rng.choice([0.0, 1e-3, 0.05]), n)
        if n and trial % 3 == 0:
            u[rng.integers(0, n, 3)] = np.nan
        if trial % 7 == 0:
            u = np.round(u, 1)  # ties
        assert first_peak_and_rebound(u) == _old_first_peak_and_rebound(u), (trial, u)


def test_trace_keeps_at_most_its_capacity_evenly_and_the_latest():
    from parmpm.output.metrics.trace import Trace

    tr = Trace(("times", "v"), capacity=8)
    for k in range(8):
        tr.add(k, 10 * k)
    assert tr.stride == 1 and tr.indices().tolist() == list(range(8))
    for k in range(8, 37):
        tr.add(k, 10 * k)
    # full at 8 kept: every 2nd, then every 4th ... always from sample 0, and the latest shown
    assert tr.count == 37 and tr.stride == 8
    assert tr.indices().tolist() == [0, 8, 16, 24, 32, 36]
    assert tr.column("v").tolist() == [0, 80, 160, 240, 320, 360]
    state = json.loads(json.dumps(tr.state()))
    again = Trace(("times", "v"), capacity=8)
    again.restore(state)
    for k in range(37, 200):
        tr.add(k, 10 * k)
        again.add(k, 10 * k)
    assert again.state() == tr.state() and len(tr.state()["rows"]) <= 8


def test_vibrating_bar_summary_streams_the_whole_history():
    """The error norms from running sums equal those of every sample kept (as before)."""
    scene, x0, mass, (E, rho, L, v0) = _vib_scene(n=40)
    m = make_metrics(_spec(scene), x0, mass)
    beta = math.pi / (2 * L)
    omega = math.sqrt(E / rho) * beta
    for t in np.linspace(0.0, 20.0, 301):
        v = np.zeros_like(x0)
        v[:, 0] = 1.01 * v0 * math.cos(omega * t) * np.sin(beta * x0[:, 0]) + 1e-4 * math.sin(7 * t)
        m.sample(t, x0, v, np.ones((x0.shape[0], 1, 1)), 1)
    num, ex = np.asarray(m.com_velocity), np.asarray(m.com_velocity_exact)  # 301: all kept
    r = m.result()
    assert r["samples"] == 301 == num.size
    assert r["com_velocity_rel_l2_error"] == pytest.approx(
        math.sqrt(np.sum((num - ex) ** 2) / np.sum(ex**2)), rel=1e-12)
    assert r["com_velocity_max_abs_error"] == np.max(np.abs(num - ex))


def test_metrics_memory_and_checkpoint_state_stay_bounded():
    """Past the trace's capacity (8,192 samples), more samples add nothing to memory
    (tracemalloc) and the state a checkpoint stores stays the trace's size. Before issue 28
    each sample appended three floats to lists (~100 bytes per sample here: ~2 MB over the
    20,000 samples below) and the state held every one (three times as large at 3N as at N)."""
    import gc
    import tracemalloc

    scene, x0, mass, _ = _vib_scene(n=8)
    m = make_metrics(_spec(scene), x0, mass)
    F = np.ones((x0.shape[0], 1, 1))
    v = np.zeros_like(x0)

    def run(a, b):
        for k in range(a, b):
            v[:, 0] = 1e-3 * math.sin(0.01 * k)
            m.sample(0.01 * k, x0, v, F, 1)

    run(0, 10_000)
    size = len(json.dumps(m.state()))
    gc.collect()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        run(10_000, 30_000)
        gc.collect()
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert grown < 16_000, f"{grown} bytes over 20,000 samples"
    assert len(json.dumps(m.state())) < 1.6 * size  # kept: 5,000 → 7,500 of 8,192 at most
    assert m.result()["samples"] == 30_000


@pytest.mark.parametrize("kind", ["hanging_bar", "tension_bar", "rotation", "manufactured"])
def test_every_kind_restores_its_record_and_continues_the_same(kind):
    """A metric restored from its JSON state (a checkpoint) and sampled on reports what the
    uninterrupted one reports."""
    import parmpm

    scene = parmpm.load_scene(kind if kind != "rotation" else "spinning_disk").spec
    from parmpm.particles.seeding import seed_bodies

    names = sorted(scene.materials)  # the material table's rows
    seeds = seed_bodies(scene.grid, scene.bodies, {n: i for i, n in enumerate(names)})
    params = np.zeros((len(names), 2))
    params[:, 1] = [scene.materials[n].density for n in names]
    P = seeds.particles(params)
    a, b = make_metrics(scene, P.x0, P.mass), make_metrics(scene, P.x0, P.mass)

    def sample(m, k):
        x = P.x0 * (1.0 + 1e-3 * math.sin(0.3 * k))
        sums, maxes = m.terms(P.gid, x, P.v, P.F, t=0.01 * k, particles=P, method=0, lcr=None,
                              inertia=None)
        m.record(0.01 * k, sums.sum(axis=0), maxes, 1 + (k > 30))

    for k in range(20):
        sample(a, k)
    b.restore(json.loads(json.dumps(a.state())))
    for k in range(20, 50):
        sample(a, k)
        sample(b, k)
    assert json.dumps(b.result()) == json.dumps(a.result())
    assert b.result()["samples"] == 50
