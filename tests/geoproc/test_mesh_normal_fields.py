"""Stored vertex normals recomputed for new positions, against analytic normals."""

from __future__ import annotations

import numpy as np

from geoproc.mesh.normal_fields import refresh_normal_fields, stored_vertex_normals


def test_sphere_normals_are_radial_on_either_side(make_fixtures):
    V, F = make_fixtures.icosphere(3)  # unit sphere, faces counter-clockwise seen from outside
    R = V / np.linalg.norm(V, axis=1, keepdims=True)
    N = stored_vertex_normals(V, F, np.tile([0.0, 0.0, 1.0], (len(V), 1)))
    assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", N, R), -1, 1))).max() < 1.0
    # stored normals that point inwards keep pointing inwards, all of them
    N_in = stored_vertex_normals(V, F, -R)
    np.testing.assert_allclose(N_in, -N, atol=1e-15)


def test_a_vertex_without_faces_keeps_its_stored_normal(make_fixtures):
    V, F = make_fixtures.icosphere(1)
    V = np.vstack([V, [[3.0, 0.0, 0.0]]])
    stored = np.tile([0.0, 1.0, 0.0], (len(V), 1))
    N = stored_vertex_normals(V, F, stored)
    assert np.array_equal(N[-1], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0, rtol=1e-14)


def test_refresh_changes_only_normal_fields_of_meshes_and_frames(make_fixtures):
    V, F = make_fixtures.icosphere(2)
    R = V / np.linalg.norm(V, axis=1, keepdims=True)
    fields = {"nx": np.zeros(len(V)), "ny": np.zeros(len(V)), "nz": np.ones(len(V)),
              "label": np.arange(len(V), dtype=float)}
    assert refresh_normal_fields(2 * V, F, fields)
    N = np.stack([fields["nx"], fields["ny"], fields["nz"]], axis=1)
    assert np.einsum("ij,ij->i", N, R).min() > 0.99 and np.array_equal(fields["label"], np.arange(len(V)))
    # per frame (T, n): each frame its own normals (the sphere within the 0.02 its facets
    # allow, the ellipsoid leaning further towards z); a point cloud's are left alone
    frames = {"nx": np.zeros((2, len(V))), "ny": np.zeros((2, len(V))), "nz": np.ones((2, len(V)))}
    squashed = V * [1.0, 1.0, 0.25]  # an ellipsoid: its normals lean towards z
    assert refresh_normal_fields(np.stack([V, squashed]), F, frames)
    nz0, nz1 = np.abs(frames["nz"][0]), np.abs(frames["nz"][1])
    assert np.abs(nz0 - np.abs(R[:, 2])).max() < 0.03 and (nz1 >= nz0 - 1e-12).all() and (nz1 > nz0 + 0.1).any()
    cloud = {"nx": np.zeros(len(V)), "ny": np.zeros(len(V)), "nz": np.ones(len(V))}
    assert not refresh_normal_fields(V, np.zeros((0, 3), dtype=np.int64), cloud)
    assert not refresh_normal_fields(V, F, {"nx": np.zeros(len(V))})


def test_faces_stored_either_way_round_and_parts_facing_either_side(make_fixtures):
    # a sphere with 30 % of its faces stored the other way round, and a second sphere whose
    # faces and stored normals all face inwards: summing the raw faces cancelled normals
    # (583 of a bunny's 3,485 came out more than 90 degrees off), and one sign for the whole
    # mesh turned the inward part's normals outwards
    V, F = make_fixtures.icosphere(2)
    R = V / np.linalg.norm(V, axis=1, keepdims=True)
    rng = np.random.default_rng(0)
    mixed = F.copy()
    turn = rng.random(len(F)) < 0.3
    mixed[turn] = mixed[turn][:, ::-1]
    V2 = np.vstack([V, V + [5.0, 0.0, 0.0]])
    F2 = np.vstack([mixed, F[:, ::-1] + len(V)])
    stored = np.vstack([R, -R]) + 0.2 * rng.standard_normal((2 * len(V), 3))  # roughly right
    N = stored_vertex_normals(V2, F2, stored)
    cos_out = np.einsum("ij,ij->i", N[: len(V)], R)
    cos_in = np.einsum("ij,ij->i", N[len(V):], -R)
    assert cos_out.min() > 0.99 and cos_in.min() > 0.99
