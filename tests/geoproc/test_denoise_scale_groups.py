"""Parts of a mesh meshed at very different scales are denoised each on its own."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.denoise import denoise_mesh
from geoproc.denoise.scale_groups import scale_groups
from tests.conftest import load_fixture_module


@pytest.fixture(scope="module")
def dfx():
    return load_fixture_module("denoise_fixtures")


def _two_parts(dfx, scale):
    """A noisy cube and a noisy copy of a second cube scaled by ``scale``, as one mesh."""
    Vn, F, _ = dfx.noisy_cube(10, sigma=0.3, seed=5)  # the larger group (by faces)
    Wn, G, _ = dfx.noisy_cube(8, sigma=0.3, seed=6)
    return Vn, F, Wn, G, np.vstack([Vn, Wn * scale + [5.0, 0.0, 0.0]]), np.vstack([F, G + len(Vn)])


def test_parts_are_grouped_by_their_edge_length(dfx):
    Vn, F, Wn, G, V, FF = _two_parts(dfx, 1e-3)
    groups = scale_groups(V, FF)
    assert groups[: len(F)].tolist() == [1] * len(F) and groups[len(F):].tolist() == [0] * len(G)
    # within the ratio (here 3), one group: nothing changes for meshes of one scale
    assert scale_groups(*_two_parts(dfx, 3.0)[4:]).max() == 0
    assert scale_groups(Vn, F).max() == 0 and scale_groups(Vn, F[:0]).shape == (0,)
    # a part whose vertices all sit at one place has no scale: it joins the smallest group
    # (alone it had been refused, its faces coinciding)
    tet = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]) + len(V)
    V2, F2 = np.vstack([V, np.zeros((4, 3))]), np.vstack([FF, tet])
    groups = scale_groups(V2, F2)
    assert groups[-4:].tolist() == [0] * 4 and groups.max() == 1
    res = denoise_mesh(V2, F2)
    assert np.array_equal(res.V[-4:], np.zeros((4, 3))) and res.info["scale_groups"] == 2


def test_each_scale_group_is_denoised_as_it_would_be_alone(dfx):
    # the small part had pulled the noise estimate to "clean": the whole mesh, noisy cube
    # included, came back unchanged (a noisy bunny at 1/1000 beside fandisk: 28.4 degrees
    # left on fandisk, 2.69 alone)
    Vn, F, Wn, G, V, FF = _two_parts(dfx, 1e-3)
    res = denoise_mesh(V, FF)
    alone_big, alone_small = denoise_mesh(Vn, F), denoise_mesh(Wn * 1e-3 + [5.0, 0.0, 0.0], G)
    assert np.array_equal(res.V[: len(Vn)], alone_big.V)
    assert np.allclose(res.V[len(Vn):], alone_small.V, rtol=0, atol=1e-12)
    assert not np.array_equal(res.V, V)
    assert res.info["scale_groups"] == 2 and denoise_mesh(Vn, F).info["scale_groups"] == 1
    assert res.info["reoriented_faces"] == alone_big.info["reoriented_faces"] + alone_small.info["reoriented_faces"]
    assert res.info["noise_roughness"] == alone_big.info["noise_roughness"]  # the largest group's schedule


def test_the_schedule_reported_is_that_of_a_group_that_was_filtered(dfx):
    # a clean large part and a noisy small one: the report had given the clean part's "nothing
    # ran" (outer_iterations 0) for a run that filtered the small part
    V = dfx.subdivided_cube(10)[0]
    F = dfx.subdivided_cube(10)[1]
    Wn, G, _ = dfx.noisy_cube(8, sigma=0.3, seed=3)
    res = denoise_mesh(np.vstack([V, Wn * 1e-3]), np.vstack([F, G + len(V)]))
    alone = denoise_mesh(Wn * 1e-3, G)
    assert res.info["outer_iterations"] == alone.info["outer_iterations"] > 0
    assert np.array_equal(res.V[: len(V)], V)


def test_a_small_part_stored_in_float32_is_denoised_as_alone(dfx):
    # the whole mesh's float32 rounding (within its limit of the large part's edges) had
    # flattened faces of a part at 1/10,000 scale thinner than 4 roundings, which alone (where
    # that rounding is past the limit of its own edges) it leaves: up to 0.14 edge lengths off
    Vn, F, Wn, G, V, FF = _two_parts(dfx, 1e-4)
    V = V.astype(np.float32).astype(np.float64)
    small = V[len(Vn):].copy()
    a, b, c = G[0]  # one face of the small part 2 % of an edge from flat (its corner c near edge ab)
    small[c] = 0.49 * small[a] + 0.49 * small[b] + 0.02 * small[c]
    small = small.astype(np.float32).astype(np.float64)
    V[len(Vn):] = small
    res, alone = denoise_mesh(V, FF), denoise_mesh(small, G)
    assert np.array_equal(res.V[len(Vn):], alone.V)
    # and so do the metrics' normals (the whole mesh's rounding had flattened that face there)
    from geoproc.denoise.metrics import face_normals

    assert np.array_equal(face_normals(V, FF)[len(F):], face_normals(small, G))
