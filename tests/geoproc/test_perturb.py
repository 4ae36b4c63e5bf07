"""perturb's noise: requested sigma (checked on the displacements against the
definition), reproducibility, impulsive fractions and outlier ranges."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.errors import InputError, UsageError
from geoproc.perturb import NoiseSpec, noise_scale, perturb_positions, point_cloud_normals, vertex_normals


@pytest.fixture(scope="module")
def sphere(make_fixtures):
    return make_fixtures.icosphere(5)  # 10,242 vertices: the sample std is within ~0.7 %


def test_noise_scale_of_a_cloud_is_the_mean_nearest_neighbour_distance():
    # a clustered cloud (a tight cluster and a sparse one), where the mean and the
    # median of the nearest-neighbour distances differ by a factor of 5 or more;
    # a point stored twice counts once
    rng = np.random.default_rng(1)
    P = np.vstack([rng.random((300, 3)) * 0.05, 2.0 + rng.random((60, 3))])
    D = np.linalg.norm(P[:, None] - P[None], axis=2)
    np.fill_diagonal(D, np.inf)
    nearest = D.min(axis=1)
    assert nearest.mean() > 5 * np.median(nearest)
    empty = np.zeros((0, 3), dtype=np.int64)
    assert noise_scale(P, empty) == pytest.approx(nearest.mean(), rel=1e-12)
    assert noise_scale(np.vstack([P, P[:1]]), empty) == pytest.approx(nearest.mean(), rel=1e-12)
    # stored twice, once rounded to float32: the near copies were each other's nearest
    # neighbours, and the unit came out at the rounding (2.6e-8 of the spacing on a torus cloud)
    twice = np.vstack([P, P.astype(np.float32).astype(np.float64)])
    assert noise_scale(twice, empty) == pytest.approx(nearest.mean(), rel=1e-5)
    # near copies of part of the cloud count once, as exact copies do: five more copies of
    # the tight cluster, each shifted by k nm, had weighted it six times (0.2286 for 0.55
    # on two grids of spacing 0.1 and 1)
    shifted = np.vstack([P] + [P[:300] + [0.0, 0.0, k * 1e-9] for k in range(1, 6)])
    assert noise_scale(shifted, empty) == pytest.approx(nearest.mean(), rel=1e-6)
    assert noise_scale(np.vstack([P] + [P[:300]] * 5), empty) == pytest.approx(nearest.mean(), rel=1e-12)


@pytest.mark.parametrize("sigma", [0.2, 0.5])
def test_normal_noise_has_requested_sigma(sphere, sigma):
    V, F = sphere
    Vn, flag = perturb_positions(V, F, NoiseSpec(sigma=sigma), np.random.default_rng(0))
    d = Vn - V
    le = noise_scale(V, F)
    N = V / np.linalg.norm(V, axis=1, keepdims=True)  # exact sphere normals
    along = np.einsum("ij,ij->i", d, N)
    assert abs(along.std() / le - sigma) < 0.05 * sigma
    # displacements are along the normal: no tangential part beyond discretization
    tangential = np.linalg.norm(d - along[:, None] * N, axis=1)
    assert tangential.max() < 0.01 * np.abs(along).max()
    assert not flag.any()


def test_normal_noise_on_faces_stored_the_other_way_round(sphere):
    # the vertex normals were taken on the faces as stored: with 30 % of them
    # reversed, normals cancelled and the noise went up to 90 degrees sideways
    V, F = sphere
    F = F.copy()
    turn = np.random.default_rng(0).random(len(F)) < 0.3
    F[turn] = F[turn][:, ::-1]
    d = perturb_positions(V, F, NoiseSpec(sigma=0.3), np.random.default_rng(0))[0] - V
    N = V / np.linalg.norm(V, axis=1, keepdims=True)
    along = np.einsum("ij,ij->i", d, N)
    tangential = np.linalg.norm(d - along[:, None] * N, axis=1)
    assert tangential.max() < 0.01 * np.abs(along).max()


def test_random_direction_noise_has_requested_sigma(sphere):
    V, F = sphere
    Vn, _ = perturb_positions(V, F, NoiseSpec(sigma=0.3, direction="random"), np.random.default_rng(1))
    rms = np.sqrt(np.mean(np.sum((Vn - V) ** 2, axis=1))) / noise_scale(V, F)
    assert abs(rms - 0.3) < 0.05 * 0.3
    # directions are isotropic: the mean normal component is small compared with sigma
    N = V / np.linalg.norm(V, axis=1, keepdims=True)
    along = np.einsum("ij,ij->i", Vn - V, N) / noise_scale(V, F)
    assert abs(np.sqrt(np.mean(along**2)) - 0.3 / np.sqrt(3)) < 0.05 * 0.3


def test_same_seed_same_output_other_seed_differs(sphere):
    V, F = sphere
    spec = NoiseSpec(sigma=0.3, impulsive=0.3, outliers=0.1)
    a = perturb_positions(V, F, spec, np.random.default_rng(9))
    b = perturb_positions(V, F, spec, np.random.default_rng(9))
    c = perturb_positions(V, F, spec, np.random.default_rng(10))
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])
    given = perturb_positions(V, F, spec, np.random.default_rng(9), scale=noise_scale(V, F))
    assert np.array_equal(given[0], a[0]) and np.array_equal(given[1], a[1])  # the caller's unit is the same
    doubled = perturb_positions(V, F, NoiseSpec(sigma=0.3), np.random.default_rng(9), scale=2 * noise_scale(V, F))
    plain = perturb_positions(V, F, NoiseSpec(sigma=0.3), np.random.default_rng(9))
    assert np.allclose(doubled[0] - V, 2 * (plain[0] - V))  # and it is the one used


def test_impulsive_moves_exactly_the_fraction(sphere):
    V, F = sphere
    Vn, _ = perturb_positions(V, F, NoiseSpec(sigma=0.5, impulsive=0.25), np.random.default_rng(2))
    moved = np.linalg.norm(Vn - V, axis=1) > 0
    assert moved.sum() == round(0.25 * len(V))


def test_outliers_flagged_and_within_range(sphere):
    V, F = sphere
    Vn, flag = perturb_positions(V, F, NoiseSpec(outliers=0.2, outlier_range=0.02), np.random.default_rng(3))
    diag = np.linalg.norm(V.max(0) - V.min(0))
    d = np.linalg.norm(Vn - V, axis=1)
    assert flag.sum() == round(0.2 * len(V))
    assert np.all(d[flag == 0] == 0)
    assert d[flag == 1].max() <= 0.02 * diag
    # uniform in the ball: the median radius is 2^(-1/3) of the range
    assert abs(np.median(d[flag == 1]) / (0.02 * diag) - 2 ** (-1 / 3)) < 0.03


def test_point_cloud_noise_uses_estimated_normals(make_fixtures):
    V, F = make_fixtures.icosphere(4)
    N = point_cloud_normals(V)
    assert np.abs(np.einsum("ij,ij->i", N, V)).min() > 0.99  # PCA normals of a sphere are radial
    P, _ = perturb_positions(V, np.zeros((0, 3), int), NoiseSpec(sigma=0.3), np.random.default_rng(4))
    along = np.einsum("ij,ij->i", P - V, V)
    assert abs(along.std() / noise_scale(V, np.zeros((0, 3), int)) - 0.3) < 0.05 * 0.3


def test_point_cloud_stored_twice_has_the_spacing_and_normals_of_one_copy(make_fixtures):
    V, _ = make_fixtures.icosphere(3)
    none = np.zeros((0, 3), int)
    twice = np.vstack([V, V])
    assert noise_scale(twice, none) == noise_scale(V, none) > 0
    N = point_cloud_normals(twice)
    assert np.array_equal(N[: len(V)], N[len(V):])
    assert np.abs(np.einsum("ij,ij->i", N, twice)).min() > 0.99
    P, _ = perturb_positions(twice, none, NoiseSpec(sigma=0.3), np.random.default_rng(4))
    along = np.einsum("ij,ij->i", P - twice, twice)
    assert abs(along.std() / noise_scale(V, none) - 0.3) < 0.1 * 0.3


def test_point_cloud_of_near_copy_clumps_takes_normals_among_the_clumps(make_fixtures):
    # each point of a sphere cloud replaced by a clump of 15 near copies (1e-7 of its spacing
    # apart): the noise unit counted a clump once, but the normals were fitted to a point's 16
    # nearest points, mostly its own clump's jitter (a sheet: median 45 degrees off its normal)
    V, _ = make_fixtures.icosphere(3)
    h = noise_scale(V, np.zeros((0, 3), int))
    rng = np.random.default_rng(5)
    clumps = (V[:, None, :] + 1e-7 * h * rng.standard_normal((len(V), 15, 3))).reshape(-1, 3)
    N = point_cloud_normals(clumps)
    radial = np.repeat(V / np.linalg.norm(V, axis=1, keepdims=True), 15, axis=0)
    assert np.abs(np.einsum("ij,ij->i", N, radial)).min() > 0.99
    assert np.array_equal(N, np.repeat(N[::15], 15, axis=0))  # one normal per clump


def test_outlier_range_ignores_vertices_no_face_uses(sphere):
    # a stray vertex kept by --no-clean had widened the box: outliers moved 700 times too far
    V, F = sphere
    V2 = np.vstack([V, [[100.0, 100.0, 100.0]]])
    Vn, flag = perturb_positions(V2, F, NoiseSpec(outliers=0.5, outlier_range=0.02), np.random.default_rng(3))
    diag = np.linalg.norm(V.max(0) - V.min(0))
    assert np.linalg.norm(Vn - V2, axis=1).max() <= 0.02 * diag


def test_vertex_normals_of_sphere_are_radial(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    assert np.einsum("ij,ij->i", vertex_normals(V, F), V).min() > 0.999
    # lists and big-endian arrays (as a file's bytes give them) are what libigl refused
    N = vertex_normals(V, F)
    assert np.array_equal(vertex_normals(V.tolist(), F.tolist()), N)
    assert np.array_equal(vertex_normals(V.astype(">f8"), F.astype(">i8")), N)


def test_vertices_without_a_normal_move_along_random_directions(make_fixtures):
    # vertices no face uses (kept by --no-clean) had all moved along +z
    V, F = make_fixtures.icosphere(2)
    stray = np.random.default_rng(1).standard_normal((200, 3))
    W = np.vstack([V, stray])
    P, _ = perturb_positions(W, F, NoiseSpec(sigma=0.3), np.random.default_rng(2))
    D = P[len(V):] - stray
    u = D / np.linalg.norm(D, axis=1, keepdims=True)
    assert np.abs(u[:, 2]).mean() < 0.7  # uniform directions: 0.5; along z: 1
    assert abs(np.sqrt((D**2).sum(axis=1).mean()) / noise_scale(W, F) - 0.3) < 0.06
    # the vertices with normals keep the noise they get without the stray ones
    Q, _ = perturb_positions(V, F, NoiseSpec(sigma=0.3), np.random.default_rng(2))
    assert np.array_equal(P[:len(V)], Q)


def test_vertex_normals_are_weighted_by_face_area(make_fixtures):
    # the benchmark protocol's noise runs along area-weighted normals: the sum of the
    # incident faces' cross products (twice their area times their unit normal), normalised;
    # on a jittered torus uniform weights tilt them by degrees, so the weighting is seen
    V, F = make_fixtures.torus()
    V = V + 0.03 * np.random.default_rng(2).standard_normal(V.shape)
    X = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    S = np.zeros_like(V)
    U = np.zeros_like(V)
    for c in range(3):
        np.add.at(S, F[:, c], X)
        np.add.at(U, F[:, c], X / np.linalg.norm(X, axis=1, keepdims=True))
    S /= np.linalg.norm(S, axis=1, keepdims=True)
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    N = vertex_normals(V, F)
    dots = np.einsum("ij,ij->i", N, S)
    assert np.abs(dots).min() > 1 - 1e-12
    assert (dots > 0).all() or (dots < 0).all()  # one orientation for the whole surface
    assert np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", S, U)), 0, 1))).max() > 2


def test_unknown_direction_is_refused(sphere):
    V, F = sphere
    with pytest.raises(InputError):
        perturb_positions(V, F, NoiseSpec(sigma=0.1, direction="sideways"), np.random.default_rng(0))


@pytest.mark.parametrize("kwargs, message", [
    ({"sigma": float("nan")}, "sigma must be a finite number"), ({"sigma": -1.0}, "sigma must be"),
    ({"outliers": 2.0}, "outliers is a fraction"), ({"impulsive": -0.5}, "impulsive is a fraction"),
    ({"outlier_range": float("inf")}, "outlier_range must be"),
])
def test_noise_settings_out_of_range_are_refused(kwargs, message):
    with pytest.raises(UsageError, match=message):
        NoiseSpec(**kwargs)


def test_perturb_takes_lists_and_needs_a_generator(make_fixtures):
    V, F = make_fixtures.icosphere(1)
    a, _ = perturb_positions(V.tolist(), F.tolist(), NoiseSpec(sigma=0.3), np.random.default_rng(1))
    b, _ = perturb_positions(V, F, NoiseSpec(sigma=0.3), np.random.default_rng(1))
    assert np.array_equal(a, b)
    with pytest.raises(TypeError, match="Generator"):
        perturb_positions(V, F, NoiseSpec(sigma=0.3), 5)
