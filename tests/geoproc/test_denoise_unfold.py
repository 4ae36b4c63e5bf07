"""Repair of folded faces after the vertex update (geoproc.denoise.vertex_update.unfold_faces)."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.denoise import DenoiseParams, denoise_errors, denoise_mesh
from geoproc.denoise.face_geometry import face_edge_neighbors, face_normals_and_areas
from geoproc.denoise.metrics import flipped_faces
from geoproc.denoise.vertex_update import folded_faces, unfold_faces, update_vertices
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
