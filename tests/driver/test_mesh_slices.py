"""How a parallel set-up cuts a mesh body's elements into the ranks' slices
(:func:`parmpm.driver.mesh_slices.element_ranges`): every element once, each rank one contiguous
run of global particle ids, in rank order, the runs as even as whole elements allow. (The slices'
particles against one rank's, bit for bit: ``tests/mpi/test_listed_share.py``.)"""
import numpy as np
import pytest

from parmpm.driver.mesh_slices import element_ranges


def _check(sizes, ranks):
    ranges = element_ranges(sizes, ranks)
    assert len(ranges) == ranks
    n = sum(e * q for e, q in sizes)
    offsets = np.cumsum([0] + [e * q for e, q in sizes])
    seen = [np.zeros(e, int) for e, _ in sizes]
    ends = []
    for r, pieces in enumerate(ranges):
        ids = []
        for b, lo, hi in pieces:
            assert 0 <= lo < hi <= sizes[b][0]
            seen[b][lo:hi] += 1
            q = sizes[b][1]
            ids.append(np.arange(offsets[b] + lo * q, offsets[b] + hi * q))
        ids = np.concatenate(ids) if ids else np.zeros(0, int)
        if ids.size:  # one contiguous run, after the ranks before it
            np.testing.assert_array_equal(ids, np.arange(ids[0], ids[0] + ids.size))
            assert not ends or ids[0] == ends[-1]
            ends.append(ids[-1] + 1)
        # the run holds the elements starting in [r n / P, (r+1) n / P)
        most = max(q for _, q in sizes)
        assert abs(ids.size - n / ranks) <= most + 1, (r, ids.size, n / ranks)
    assert all(np.all(s == 1) for s in seen)


@pytest.mark.parametrize("ranks", [1, 2, 3, 4, 7, 16])
def test_one_block_cut_into_even_runs(ranks):
    _check([(1000, 4)], ranks)


@pytest.mark.parametrize("seed", range(20))
def test_random_blocks_cut_into_contiguous_runs(seed):
    rng = np.random.default_rng(seed)
    k = int(rng.integers(1, 5))
    sizes = [(int(rng.integers(0, 50)), int(rng.choice([3, 4, 12, 27, 108]))) for _ in range(k)]
    if sum(e for e, _ in sizes) == 0:
        sizes.append((1, 3))
    _check(sizes, int(rng.integers(1, 9)))


def test_more_ranks_than_elements_leaves_some_empty():
    ranges = element_ranges([(2, 27)], 5)
    assert sum(bool(p) for p in ranges) == 2
    assert [p for p in ranges if p] == [[(0, 0, 1)], [(0, 1, 2)]]


def _mesh():
    from parmpm.io.mesh_file import MeshBlock, VolumeMesh
    from mesh_harness import polar

    pts, quads, fan = polar(0.0, 1.0, 3, 16)
    blocks = tuple(MeshBlock(t, c.astype(np.int64), np.zeros(len(c), np.int64))
                   for t, c in (("triangle", fan), ("quad", quads)))
    return VolumeMesh(pts, blocks)


@pytest.mark.parametrize("ranks", [1, 2, 3, 5])
def test_slices_make_the_whole_meshs_particles_bit_for_bit(ranks):
    """Each rank's part (its elements over only the nodes they use, renumbered) makes exactly
    its run of the one-pass particles."""
    from types import SimpleNamespace

    from parmpm.driver.mesh_slices import _dealer, _made
    from parmpm.geometry.mesh import mesh_particles

    mesh = _mesh()
    x, vol, _ = mesh_particles(mesh.points, mesh.blocks, 2)
    deal = _dealer(mesh, 2, ranks, len(vol), "bodies.0.file")
    body = SimpleNamespace(file="disk.vtu")
    got = [_made(deal(r), body, 0, "s.toml") for r in range(ranks)]
    begins = [g["begin"] for g in got if g["vol"].size]
    assert begins == sorted(begins) and begins[0] == 0
    np.testing.assert_array_equal(np.concatenate([g["x"] for g in got]), x)
    np.testing.assert_array_equal(np.concatenate([g["vol"] for g in got]), vol)


def test_a_bad_element_in_a_slice_names_the_files_nodes_and_the_body():
    from types import SimpleNamespace

    from parmpm.core.errors import SceneError
    from parmpm.driver.mesh_slices import _dealer, _made
    from parmpm.io.mesh_file import MeshBlock, VolumeMesh

    mesh = _mesh()
    quads = mesh.blocks[1].cells.copy()
    quads[-1] = quads[-1][::-1]  # the last quad clockwise: inverted
    mesh = VolumeMesh(mesh.points, (mesh.blocks[0], MeshBlock("quad", quads, mesh.blocks[1].group)))
    deal = _dealer(mesh, 1, 2, 16 * 3 + 32 * 4, "bodies.3.file")
    body = SimpleNamespace(file="disk.vtu")
    _made(deal(0), body, 3, "s.toml")  # rank 0's half holds no bad element
    with pytest.raises(SceneError) as err:
        _made(deal(1), body, 3, "s.toml")
    text = str(err.value)
    assert text.startswith("scene 's.toml': bodies.3.file: mesh 'disk.vtu': element 47 (quad, "
                           f"nodes {quads[-1].tolist()}"), text
    assert "is inverted" in text


def test_a_mesh_changed_since_the_scene_was_read_is_refused():
    from parmpm.core.errors import SceneError
    from parmpm.driver.mesh_slices import _dealer

    with pytest.raises(SceneError, match="bodies.0.file: the mesh made 100 particles when the "
                                         "scene was read and 176 now"):
        _dealer(_mesh(), 1, 2, 100, "bodies.0.file")
