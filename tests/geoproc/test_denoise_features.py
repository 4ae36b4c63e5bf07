"""l1 feature identification (sparse normal Laplacian J_i = n_i . (L_i v)):
the ADMM solver against cvxpy, exact answers on clean shapes with known creases,
and the features of denoised meshes against their clean references."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.denoise import DenoiseParams, denoise_mesh
from geoproc.denoise.face_geometry import face_edge_neighbors, face_normals_and_areas
from geoproc.denoise.features import (
    default_lam,
    dihedral_feature_faces,
    l1_feature_faces,
    l1_feature_vertices,
    l1_sparse_normal_laplacian,
    normal_laplacian,
)
from geoproc.mesh import load_mesh
from tests.conftest import load_fixture_module


@pytest.fixture(scope="module")
def dfx():
    return load_fixture_module("denoise_fixtures")


def _crease_faces(V_clean, F, angle_deg=30.0):
    """Ground truth: faces with an edge whose dihedral angle on the clean mesh exceeds angle_deg."""
    N, _ = face_normals_and_areas(V_clean, F)
    return dihedral_feature_faces(N, face_edge_neighbors(F), angle_deg) > 0


def _precision_recall(pred, truth):
    pred = np.asarray(pred) > 0
    tp = (pred & truth).sum()
    return tp / max(pred.sum(), 1), tp / max(truth.sum(), 1)


def _folded_grid(make_fixtures, angle_deg):
    """The 21 x 21 grid folded along x = 0.5 by ``angle_deg``; returns V, F and the fold's vertices."""
    V, F = make_fixtures.grid()
    mid = 0.5
    r = V[:, 0] - mid
    t = np.radians(angle_deg)
    X = V.copy()
    X[r > 0, 0] = mid + r[r > 0] * np.cos(t)
    X[r > 0, 2] = r[r > 0] * np.sin(t)
    return X, F, np.isclose(V[:, 0], mid)


def test_admm_matches_cvxpy(make_fixtures):
    cp = pytest.importorskip("cvxpy")
    V, F, _ = _folded_grid(make_fixtures, 60.0)
    V = V + 0.01 * np.random.default_rng(0).standard_normal(V.shape)  # 0.2 edge lengths
    J0, A, _ = normal_laplacian(V, F)
    lam = default_lam(J0)
    d, z, _, ok = l1_sparse_normal_laplacian(J0, A, lam, tol=1e-9, max_iter=20000)
    assert ok
    x = cp.Variable(len(J0))
    problem = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(x) + lam * cp.norm1(J0 + A @ x)))
    problem.solve(solver=cp.CLARABEL)
    ours = 0.5 * d @ d + lam * np.abs(J0 + A @ d).sum()
    assert ours == pytest.approx(problem.value, rel=1e-6)
    assert np.abs(d - x.value).max() < 1e-4
    # z is exactly sparse (the shrinkage) and matches the reference
    ref = J0 + A @ x.value
    assert (z == 0).mean() > 0.5 and (J0 == 0).sum() == 0
    assert np.abs(z - ref).max() < 1e-4


def test_clean_cube_edges_are_exact(dfx):
    V, F = dfx.subdivided_cube(16)
    res = l1_feature_vertices(V, F)
    on_edge_vertex = (np.abs(V) > 1 - 1e-9).sum(axis=1) >= 2
    assert np.array_equal(res.feature, on_edge_vertex)
    feature, _ = l1_feature_faces(V, F)
    precision, recall = _precision_recall(feature, _crease_faces(V, F))
    # the only extra faces are the corner triangles spanning two edge vertices
    assert recall == 1.0 and precision > 0.96


@pytest.mark.parametrize("angle", [30.0, 60.0, 90.0])
def test_fold_is_found(make_fixtures, angle):
    V, F, fold = _folded_grid(make_fixtures, angle)
    res = l1_feature_vertices(V, F)
    assert np.array_equal(res.feature, fold)
    # |J| on the fold grows like sin(angle / 2)
    assert np.abs(res.J0[fold]).min() == pytest.approx(0.588 * np.sin(np.radians(angle) / 2), rel=0.03)
    feature, _ = l1_feature_faces(V, F)
    assert np.array_equal(feature > 0, _crease_faces(V, F, 0.5 * angle))


def test_shallow_fold_and_smooth_shapes_have_no_features(make_fixtures):
    V, F, _ = _folded_grid(make_fixtures, 10.0)
    assert not l1_feature_vertices(V, F).feature.any()
    for name in ("icosphere", "torus"):
        V, F = getattr(make_fixtures, name)()
        assert l1_feature_faces(V, F)[0].sum() == 0


def test_noisy_cube_features_after_denoising(dfx):
    Vn, F, V = dfx.noisy_cube(n=16, sigma=0.3, seed=5)
    res = denoise_mesh(Vn, F, params=DenoiseParams(features="l1"))
    assert res.info["feature_method"] == "l1"
    precision, recall = _precision_recall(res.feature, _crease_faces(V, F))
    assert precision > 0.92 and recall > 0.94  # measured 0.937, 0.957
    old = denoise_mesh(Vn, F)  # the default: dihedral
    assert np.array_equal(old.V, res.V)  # the feature choice does not change the geometry
    p_old, r_old = _precision_recall(old.feature, _crease_faces(V, F))
    assert p_old > 0.9 and r_old > 0.9


def test_l1_on_the_noisy_input_removes_most_oscillation(dfx):
    # on the raw noisy cube the l1 fit zeroes the normal Laplacian of most flat vertices
    Vn, F, V = dfx.noisy_cube(n=16, sigma=0.3, seed=5)
    res = l1_feature_vertices(Vn, F, tau=0.0)
    flat = (np.abs(V) > 1 - 1e-9).sum(axis=1) < 2
    assert (res.J0[flat] != 0).mean() > 0.99
    assert (res.J[flat] != 0).mean() < 0.2


def test_l1_weight_ignores_vertices_no_face_uses(dfx):
    # their J of 0 entered the spread that sets lambda: half a fandisk kept with its unused
    # vertices (--no-clean) had lambda 0.005 instead of 0.12 and 118 other feature faces
    Vn, F, _ = dfx.noisy_cube(n=16, sigma=0.3, seed=5)
    extra = np.random.default_rng(0).random((3 * len(Vn), 3))
    a = l1_feature_vertices(Vn, F)
    b = l1_feature_vertices(np.vstack([Vn, extra]), F)
    assert b.lam == a.lam and np.array_equal(b.feature[: len(Vn)], a.feature) and not b.feature[len(Vn):].any()


@pytest.mark.slow
@pytest.mark.parametrize("name, p_min, r_min", [("Fandisk0.3", 0.88, 0.89), ("Twelve0.5Impulsive", 0.85, 0.66)])
def test_shared_pair_features(shared_data, name, p_min, r_min):
    a = load_mesh(shared_data / "denoise" / name / "Noisy.obj", clean=False)
    b = load_mesh(shared_data / "denoise" / name / "Original.obj", clean=False)
    res = denoise_mesh(a.V, a.F, params=DenoiseParams(features="l1"))
    precision, recall = _precision_recall(res.feature, _crease_faces(b.V, a.F))
    assert precision > p_min and recall > r_min
