"""The faces' structures shared by the frames of an animation (FaceConnectivity)."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.denoise import denoise_mesh, face_connectivity
from geoproc.denoise.face_geometry import face_edge_neighbors, face_ring_csr
from geoproc.errors import InputError


def test_faces_are_turned_to_agree_with_their_neighbours(make_fixtures):
    V, F = make_fixtures.icosphere(2)
    turned = np.random.default_rng(0).random(len(F)) < 0.3
    Fm = F.copy()
    Fm[turned] = Fm[turned][:, ::-1]
    conn = face_connectivity(Fm, len(V))
    assert np.array_equal(conn.flip, turned) or np.array_equal(conn.flip, ~turned)
    # consistently oriented: every directed edge of the closed sphere occurs exactly once
    directed = np.concatenate([conn.F[:, [0, 1]], conn.F[:, [1, 2]], conn.F[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == 3 * len(F)
    assert (conn.edge_nb >= 0).all() and conn.matches(Fm, len(V)) and not conn.matches(F, len(V))


def test_given_connectivity_gives_the_same_result_and_must_match(dfx_noisy_cube):
    V, F, _ = dfx_noisy_cube
    conn = face_connectivity(F, len(V))
    a, b = denoise_mesh(V, F), denoise_mesh(V, F, connectivity=conn)
    assert np.array_equal(a.V, b.V) and np.array_equal(a.feature, b.feature)
    with pytest.raises(ValueError, match="other faces"):
        denoise_mesh(V, F[::-1], connectivity=conn)
    with pytest.raises(ValueError, match="other faces"):
        denoise_mesh(np.vstack([V, V[:1]]), F, connectivity=conn)


def test_a_reference_with_the_other_winding_is_matched(dfx_noisy_cube):
    # a reference written with every face reversed, alone or with its vertices renumbered
    # (an STL copy), is the same mesh; it had been refused as "other faces"
    from geoproc.denoise.validate import reference_in_input_order

    _, F, V = dfx_noisy_cube
    n = len(V)
    assert np.array_equal(reference_in_input_order(F, n, F[:, ::-1], V, "r.obj"), V)
    pv = np.random.default_rng(3).permutation(n)
    inv = np.argsort(pv)
    for corners in ([0, 2, 1], [2, 1, 0], [1, 2, 0]):
        assert np.array_equal(reference_in_input_order(F, n, inv[F][:, corners], V[pv], "r.obj"), V)
    swapped = F.copy()
    swapped[[0, 1]] = swapped[[1, 0]]
    with pytest.raises(InputError, match="other faces"):
        reference_in_input_order(F, n, swapped[:, ::-1], V, "r.obj")


def test_non_manifold_faces_are_refused_once():
    F = np.array([[0, 1, 2], [0, 2, 1], [0, 1, 3]])
    with pytest.raises(InputError, match="two faces per edge"):
        face_connectivity(F, 4)


@pytest.fixture(scope="module")
def dfx_noisy_cube():
    from tests.conftest import load_fixture_module

    return load_fixture_module("denoise_fixtures").noisy_cube(n=8, sigma=0.3, seed=2)


def test_renumbered_faces_give_the_input_order_back(dfx_noisy_cube):
    # the rounds run in Z-order; shuffling the input's vertices and faces must give
    # the same positions, normals and features for the same vertices and faces
    V, F, V_clean = dfx_noisy_cube
    rng = np.random.default_rng(2)
    pv, pf = rng.permutation(len(V)), rng.permutation(len(F))
    inv = np.argsort(pv)
    a = denoise_mesh(V, F)
    b = denoise_mesh(V[pv], inv[F[pf]])
    assert np.abs(b.V - a.V[pv]).max() < 1e-9
    assert np.abs(b.normals - a.normals[pf]).max() < 1e-9
    assert np.array_equal(b.feature, a.feature[pf])
    conn = face_connectivity(F, len(V))
    vo, fo, work = conn.work_order(V)
    assert np.array_equal(np.sort(vo), np.arange(len(V))) and np.array_equal(np.sort(fo), np.arange(len(F)))
    assert np.array_equal(np.argsort(vo)[conn.F[fo]], work.F) and work is conn.work_order(V[::-1])[2]
    assert np.array_equal(work.edge_nb, face_edge_neighbors(work.F))
    assert all(np.array_equal(x, y) for x, y in zip(work.ring, face_ring_csr(work.F, len(V), 1), strict=True))
