"""Repair of folded faces after the vertex update (geoproc.denoise.vertex_update.unfold_faces)."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.denoise import DenoiseParams, denoise_errors, denoise_mesh
from geoproc.denoise.face_geometry import face_edge_neighbors, face_normals_and_areas
from geoproc.denoise.metrics import flipped_faces
from geoproc.denoise.vertex_update import (
    folded_faces,
    unfold_faces,
    update_vertices,
    vertex_face_csr,
    withhold_folding_steps,
)
from geoproc.mesh import load_mesh
from geoproc.perturb import NoiseSpec, perturb_positions


def _lateral_fold(make_fixtures):
    """Clean 11 x 11 grid (spacing 0.1) and a noisy copy whose centre vertex is
    pushed 1.5 spacings sideways, across its neighbours' edges: two faces fold."""
    V, F = make_fixtures.grid(11)
    Vn = V.copy()
    centre = 5 * 11 + 5
    Vn[centre, :2] += [0.15, 0.03]
    Vn[:, 2] += 0.01 * np.random.default_rng(0).standard_normal(len(V))
    return V, F, Vn, centre


def test_unfold_repairs_a_lateral_fold_that_the_update_cannot(make_fixtures):
    V, F, Vn, centre = _lateral_fold(make_fixtures)
    target = np.tile([0.0, 0.0, 1.0], (len(F), 1))  # the clean normals
    assert len(flipped_faces(Vn, F, V)) == 2
    # the normal-fitting update moves vertices only along the targets: the fold stays
    X = update_vertices(Vn, F, target, iterations=50)
    assert len(flipped_faces(X, F, V)) == 2
    for edge_nb in (None, face_edge_neighbors(F)):
        Y, left = unfold_faces(X, F, target, edge_nb)
        assert left == 0
        assert len(flipped_faces(Y, F, V)) == 0  # against the clean grid
        assert np.linalg.norm(Y[centre, :2] - V[centre, :2]) < 0.06  # was 0.153 away
        assert denoise_errors(Y, F, V)["max_normal_angle_deg"] < 60.0


def test_folded_faces_sees_folds_against_smooth_neighbours_only(make_fixtures):
    V, F, Vn, _ = _lateral_fold(make_fixtures)
    N, _ = face_normals_and_areas(Vn, F)
    edge_nb = face_edge_neighbors(F)
    bad = flipped_faces(Vn, F, V)
    target = np.tile([0.0, 0.0, 1.0], (len(F), 1))
    # targets halfway between the fold and +z agree with both: the target test
    # misses the fold, the neighbours (smooth targets, folded geometry) reveal it
    half = N[bad] + [0.0, 0.0, 1.0]
    target[bad] = half / np.linalg.norm(half, axis=1, keepdims=True)
    assert (target[bad] @ [0.0, 0.0, 1.0] > 0).all() and (np.einsum("ij,ij->i", target[bad], N[bad]) > 0).all()
    assert not folded_faces(Vn, F, target).any()
    assert np.array_equal(np.flatnonzero(folded_faces(Vn, F, target, edge_nb)), bad)
    # a clean cube: 90-degree creases are not folds
    C, FC = make_fixtures.cube(8)
    NC, _ = face_normals_and_areas(C, FC)
    assert not folded_faces(C, FC, NC, face_edge_neighbors(FC)).any()


def test_denoise_creates_no_flips_on_a_noisy_organic_mesh(shared_data):
    m = load_mesh(shared_data / "meshes" / "fertility.off")
    Vn, _ = perturb_positions(m.V, m.F, NoiseSpec(sigma=0.5), np.random.default_rng(1))
    noisy = set(flipped_faces(Vn, m.F, m.V).tolist())

    def run(rounds):
        res = denoise_mesh(Vn, m.F, params=DenoiseParams(unfold_rounds=rounds))
        new = [f for f in flipped_faces(res.V, m.F, m.V).tolist() if f not in noisy]
        return len(new), denoise_errors(res.V, m.F, m.V)["mean_normal_angle_deg"], res.info

    new_off, theta_off, _ = run(0)
    new_on, theta_on, info = run(5)
    assert new_off >= 5  # without the repair the update folds faces here (7 at the time of writing)
    assert new_on == 0
    assert info["folded_faces"] <= 8  # a few may stay held by the guard (5 at the time of writing)
    assert theta_on <= theta_off + 0.05
    assert theta_on == pytest.approx(8.0, abs=0.3)


def _face_cross_np(X, F):
    return np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])


def _withhold_reference(X, delta, F, target, keep):
    """The guard's definition, pass by pass over every face (numpy)."""
    delta = delta.copy()
    R0 = _face_cross_np(X, F)
    moving = (delta != 0).any(axis=1)
    guarded = moving[F].any(axis=1) & (np.einsum("ij,ij->i", R0, target) > 0)
    check_keep = guarded & (np.einsum("ij,ij->i", R0, keep) > 0)
    while True:
        R1 = _face_cross_np(X + delta, F)
        against_keep = check_keep & (np.einsum("ij,ij->i", R1, keep) <= 0)
        bad = guarded & ((np.einsum("ij,ij->i", R1, target) <= 0) | against_keep)
        if not bad.any():
            return delta
        delta[F[bad].reshape(-1)] = 0.0


def test_withheld_steps_match_the_guards_definition(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    rng = np.random.default_rng(4)
    X = V + 0.02 * rng.standard_normal(V.shape)
    target, _ = face_normals_and_areas(V, F)
    keep, _ = face_normals_and_areas(X, F)
    for scale in (0.03, 0.05, 0.08):  # steps of a fifth to half the edge length
        delta = scale * rng.standard_normal(V.shape)
        delta[rng.random(len(V)) < 0.2] = 0.0
        expect = _withhold_reference(X, delta, F, target, keep)
        got = withhold_folding_steps(X, delta.copy(), F, target, keep)
        assert np.array_equal(got, expect)
        frozen = (expect == 0).all(axis=1) & (delta != 0).any(axis=1)
        assert 0 < frozen.sum() < (delta != 0).any(axis=1).sum()  # the guard withholds some steps, not all


def test_folded_faces_matches_its_definition(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    rng = np.random.default_rng(5)
    X = V + 0.05 * rng.standard_normal(V.shape)
    target, _ = face_normals_and_areas(V, F)
    edge_nb = face_edge_neighbors(F)
    R = _face_cross_np(X, F)
    against = np.einsum("ij,ij->i", R, target) < 0
    nb = edge_nb  # a closed mesh: every face has three edge neighbours
    geometry = R[nb].sum(axis=1)
    area2 = np.linalg.norm(R[nb], axis=2)
    mean_target = np.einsum("ij,ijk->ik", area2, target[nb])
    expect = against | ((np.einsum("ij,ij->i", R, geometry) < 0) & (np.einsum("ij,ij->i", target, mean_target) > 0))
    assert against.any() and (expect & ~against).any()
    assert np.array_equal(folded_faces(X, F, target), against)
    assert np.array_equal(folded_faces(X, F, target, edge_nb), expect)
    some = np.flatnonzero(expect)[:5]
    assert np.array_equal(folded_faces(X, F, target, edge_nb, some), expect[some])


def test_vertex_face_csr_lists_the_faces_around_each_vertex(make_fixtures):
    V, F = make_fixtures.torus(nu=8, nv=6)
    indptr, faces = vertex_face_csr(F, len(V) + 1)  # one isolated vertex at the end
    assert indptr[-1] == 3 * len(F) and indptr[-1] == indptr[-2]
    for v in range(len(V)):
        assert list(faces[indptr[v]:indptr[v + 1]]) == [f for f in range(len(F)) if v in F[f]]
