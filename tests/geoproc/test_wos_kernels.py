"""Harmonic kernels: Laplacian ~ 0 by finite differences, gradients, fast evaluation paths."""

import numpy as np
import pytest

from geoproc.wos.domain import build_domain
from geoproc.wos.fit import angle_kernels, green_kernels
from geoproc.wos.kernels import (
    ANGLE,
    GREEN,
    cv_gradient,
    cv_value,
    green_kernel,
    kernel_matrix,
    kernel_normal_matrix,
    segment_angle_kernel,
)
from geoproc.wos.problem import WalkProblem
from tests.conftest import load_fixture_module


def _load_wos_fixtures():
    """fixtures/wos_fixtures.py, loaded the way conftest loads make_fixtures."""
    return load_fixture_module("wos_fixtures")


wf = _load_wos_fixtures()
# step of the 5-point Laplacian: truncation ~ h^2 |d4 phi| / 6, round-off ~ 4 eps |phi| / h^2
H = 1e-4


def _laplacian(f, X):
    e = np.array([[H, 0.0]]), np.array([[0.0, H]])
    return (f(X + e[0]) + f(X - e[0]) + f(X + e[1]) + f(X - e[1]) - 4 * f(X)) / H**2


def test_green_kernel_is_harmonic_away_from_center():
    rng = np.random.default_rng(0)
    Y = np.array([[2.0, -1.0], [-1.5, 0.5]])
    X = rng.uniform(-1, 1, (40, 2))
    lap = _laplacian(lambda P: green_kernel(P, Y), X)
    # |d2 phi| ~ 1/(2 pi r^2) ~ 0.1 here, so a non-harmonic error would be that large
    assert np.abs(lap).max() < 1e-5
    # and it is the fundamental solution: the flux through a circle around the center is -1
    t = np.linspace(0, 2 * np.pi, 2001)[:-1]
    C = Y[0] + 0.3 * np.c_[np.cos(t), np.sin(t)]
    flux = (kernel_normal_matrix(C, np.c_[np.cos(t), np.sin(t)],
                                 _single_green(Y[0]))[:, 0] * 0.3 * 2 * np.pi / len(t)).sum()
    assert flux == pytest.approx(-1.0, abs=1e-9)


def _single_green(y):
    from geoproc.wos.kernels import KernelSet

    P = np.asarray([y], dtype=float)
    return KernelSet(GREEN, P, P.copy(), np.zeros(1, dtype=np.int64), 1)


def test_segment_angle_kernel_is_harmonic_off_segment():
    rng = np.random.default_rng(1)
    A = np.array([[0.0, 0.0], [1.0, -0.5]])
    B = np.array([[1.0, 0.2], [0.3, 1.5]])
    X = rng.uniform(-1, 2, (400, 2))
    # stay away from the segments (where the kernel jumps by 2 pi) and their endpoints
    from geoproc.wos.closest import build_segment_grid, closest_points

    d, _, _ = closest_points(X, A, B, build_segment_grid(A, B))
    X = X[d > 0.2]
    lap = _laplacian(lambda P: segment_angle_kernel(P, A, B), X)
    # at r >= 0.2 the single second derivatives reach 1/r^2 ~ 25; their sum must vanish
    # up to h^2 |d4| / 6 ~ 1e-6 and round-off ~ 1e-7
    assert np.abs(lap).max() < 2e-5
    # the angle a segment subtends at a point on its left is positive, and pi just beside it
    assert segment_angle_kernel(np.array([[0.5, 1e-9]]), np.array([[0.0, 0.0]]),
                                np.array([[1.0, 0.0]]))[0, 0] == pytest.approx(np.pi, abs=1e-6)


def test_closed_loop_angle_sum_is_winding_number():
    d = build_domain(wf.glyph("B", 128)["loops"])
    ks = angle_kernels(d, 20)
    rng = np.random.default_rng(2)
    lo, hi = d.bbox
    X = rng.uniform(lo, hi, (300, 2))
    total = kernel_matrix(X, ks).sum(axis=1)
    np.testing.assert_allclose(total, np.where(d.contains(X), 2 * np.pi, 0.0), atol=1e-9)


@pytest.mark.parametrize("family", ["green", "angle"])
def test_numba_value_and_gradient_match_numpy(family):
    d = build_domain(wf.star(128, 5, 0.3)["loops"])
    pb = WalkProblem(d, None if False else _expr("x"), None, 1e-3)
    ks = green_kernels(d, 30, pb.distance) if family == "green" else angle_kernels(d, 30)
    sigma = np.random.default_rng(3).standard_normal(ks.M)
    W = ks.weights(sigma)
    rng = np.random.default_rng(4)
    X = rng.uniform(-1.4, 1.4, (300, 2))
    X = X[pb.distance(X) > 1e-2]
    want = kernel_matrix(X, ks) @ sigma
    got = np.array([cv_value(x, y, ks.kind, ks.P, ks.Q, W, ks.arcs, ks.boxes) for x, y in X])
    # the angle kernel's chord shortcut equals the per-segment sum (no 2 pi jumps)
    np.testing.assert_allclose(got, want, atol=1e-9)
    for nrm in (np.array([1.0, 0.0]), np.array([0.0, 1.0])):
        g_np = kernel_normal_matrix(X, np.tile(nrm, (len(X), 1)), ks) @ sigma
        g_nb = np.array([np.dot(cv_gradient(x, y, ks.kind, ks.P, ks.Q, W, ks.arcs), nrm)
                         for x, y in X])
        np.testing.assert_allclose(g_nb, g_np, rtol=1e-9, atol=1e-9)
        fd = (kernel_matrix(X + 1e-6 * nrm, ks) - kernel_matrix(X - 1e-6 * nrm, ks)) @ sigma / 2e-6
        np.testing.assert_allclose(g_np, fd, rtol=1e-4, atol=1e-4)
    assert ks.kind == (GREEN if family == "green" else ANGLE)


def test_green_centers_lie_outside_the_domain():
    for name in ("u_shape", "square_holes", "glyph_B"):
        dom = dict((n, dm) for n, dm, _ in wf.domains())[name]
        d = build_domain(dom["loops"])
        pb = WalkProblem(d, _expr("x"), None, 1e-3)
        ks = green_kernels(d, 80, pb.distance)
        assert ks.M >= 60, name
        assert not d.contains(ks.P).any(), name
        assert pb.distance(ks.P).min() > 0, name


def _expr(text):
    from geoproc.wos.expression import parse_expression

    return parse_expression(text)


def test_ridge_fit_without_ridge_on_too_few_rows_is_the_minimum_norm_fit():
    from geoproc.wos.fit import ridge_fit

    rng = np.random.default_rng(0)
    Phi, u = rng.random((2, 5)), np.array([1.0, 3.0])  # 2 rows, 5 kernels + a constant: singular normal matrix
    sigma, b, scale = ridge_fit(Phi, u, 0.0)
    assert np.allclose(Phi @ sigma + b, u, atol=1e-10)  # interpolates the rows
    mean = Phi.mean(axis=0)
    D = np.hstack([(Phi - mean) / scale, np.ones((2, 1))])  # the fit's centred, scaled columns
    x_min = np.linalg.pinv(D) @ u  # the minimum-norm solution, independently
    assert np.allclose(np.append(sigma * scale, b + sigma @ mean), x_min, atol=1e-10)


def test_ridge_fit_penalizes_the_coefficients_and_not_the_constant():
    from geoproc.wos.fit import ridge_fit

    # min |D x - u|^2 + alpha |x[:M]|^2 over the centred, scaled columns D and a free
    # constant, solved independently as one stacked least-squares problem
    rng = np.random.default_rng(2)
    Phi = rng.random((40, 6)) * [1, 2, 3, 4, 5, 6] + 10.0
    u = 5.0 + Phi @ rng.standard_normal(6) + 0.1 * rng.standard_normal(40)
    alpha = 10.0
    sigma, b, scale = ridge_fit(Phi, u, alpha)
    mean = Phi.mean(axis=0)
    D = np.hstack([(Phi - mean) / Phi.std(axis=0), np.ones((40, 1))])
    R = np.hstack([np.sqrt(alpha) * np.eye(6), np.zeros((6, 1))])
    x = np.linalg.lstsq(np.vstack([D, R]), np.concatenate([u, np.zeros(6)]), rcond=None)[0]
    np.testing.assert_allclose(sigma * scale, x[:6], rtol=1e-9, atol=1e-12)
    assert b == pytest.approx(x[6] - sigma @ mean, rel=1e-9)


def test_ridge_fit_gives_a_column_constant_up_to_rounding_no_weight():
    # an angle kernel over a whole closed loop is 2 pi (or 0, for a hole) inside the domain,
    # give or take 1e-16: scaled by that rounding it had taken a coefficient near 1e14
    from geoproc.wos.fit import ridge_fit

    rng = np.random.default_rng(3)
    real = rng.random((50, 2))
    for flat in (2 * np.pi + 3e-16 * rng.standard_normal(50), 1e-16 * rng.standard_normal(50)):
        Phi = np.column_stack([real, flat])
        u = 1.0 + real @ [2.0, -1.0]
        for alpha in (0.0, 0.1):
            sigma, b, scale = ridge_fit(Phi, u, alpha)
            assert sigma[2] == 0.0 and scale[2] == 1.0
            assert np.abs(Phi @ sigma + b - u).max() < (1e-9 if alpha == 0 else 0.2)
    # with one fit point every column is flat: the Neumann rows alone set the coefficients
    Phi, dPhi = rng.random((1, 3)), rng.random((5, 3))
    sigma, _, _ = ridge_fit(Phi, np.array([1.0]), 0.0, dPhi, dPhi @ [1.0, 2.0, 3.0])
    np.testing.assert_allclose(sigma, [1.0, 2.0, 3.0], rtol=1e-9)


def test_cv_angle_with_one_kernel_per_closed_loop_is_the_naive_estimate():
    # one kernel per loop is constant in the domain: the control variate is a constant and the
    # estimate the naive one (a star with --kernels 1 had rmse 2.9 against 0.046, its error
    # bars covering 4 % of the points)
    from geoproc.wos import build_domain, parse_expression, solve_laplace
    from tests.conftest import load_fixture_module

    wf = load_fixture_module("wos_fixtures")
    dom = build_domain(wf.star(256)["loops"])
    g = parse_expression("x**3 - 3*x*y**2")
    kw = dict(walks=32, grid=12, exact=True, seed=1)
    naive = solve_laplace(dom, g, **kw).metrics
    angle = solve_laplace(dom, g, method="cv-angle", kernels=1, **kw).metrics
    assert angle["kernels_used"] == 1
    assert angle["rmse"] == pytest.approx(naive["rmse"], rel=1e-6)


def test_ridge_fit_does_not_depend_on_the_length_unit():
    from geoproc.wos.fit import ridge_fit

    # Green kernels -log|x - c| / 2 pi measured in another unit (x 1000) differ by a constant
    rng = np.random.default_rng(1)
    X, C = rng.uniform(-0.6, 0.6, (300, 2)), 1.5 * np.exp(1j * np.linspace(0, 2 * np.pi, 40, endpoint=False))
    Phi = -np.log(np.abs(X[:, :1] + 1j * X[:, 1:] - C[None, :])) / (2 * np.pi)
    u = X[:, 0] ** 3 - 3 * X[:, 0] * X[:, 1] ** 2
    shifted = Phi - np.log(1000.0) / (2 * np.pi)
    a, b = ridge_fit(Phi, u, 0.1), ridge_fit(shifted, u, 0.1)
    np.testing.assert_allclose(b[0], a[0], rtol=0, atol=1e-9 * np.abs(a[0]).max())
    np.testing.assert_allclose(Phi @ a[0] + a[1], shifted @ b[0] + b[1], rtol=0, atol=1e-9)


def test_design_matrices_are_built_a_block_of_elements_at_a_time(monkeypatch):
    # every point-element pair at once had taken 11 GB for 640 fit points on a
    # 320,000-segment domain (cv-angle); blocks give the same sums, bit for bit
    import tracemalloc

    from geoproc.wos import kernels as kn

    rng = np.random.default_rng(5)
    t = np.sort(rng.random(20001)) * 2 * np.pi
    ring = np.column_stack([np.cos(t), np.sin(t)])
    P, Q = ring[:-1], ring[1:]
    col = np.repeat(np.arange(40), 500)
    ks = kn.KernelSet(kn.ANGLE, P, Q, col.astype(np.int64), 40)
    X = 0.5 * rng.random((640, 2)) - 0.25
    N = rng.normal(size=(640, 2))
    tracemalloc.start()
    A, D = kn.kernel_matrix(X, ks), kn.kernel_normal_matrix(X, N, ks)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 150e6, peak  # all 12.8 M pairs at once: about 500 MB
    monkeypatch.setattr(kn, "ELEMENT_BLOCK", 7 * 640)
    np.testing.assert_array_equal(kn.kernel_matrix(X, ks), A)
    np.testing.assert_array_equal(kn.kernel_normal_matrix(X, N, ks), D)
    green = kn.KernelSet(kn.GREEN, P[:30], P[:30].copy(), np.arange(30, dtype=np.int64), 30)
    monkeypatch.setattr(kn, "ELEMENT_BLOCK", 640)
    one = kn.kernel_matrix(X, green)
    monkeypatch.setattr(kn, "ELEMENT_BLOCK", 1 << 21)
    np.testing.assert_array_equal(kn.kernel_matrix(X, green), one)
