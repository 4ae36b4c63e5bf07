"""Walk on Spheres / Stars estimates against analytic harmonic solutions."""

import numba
import numpy as np
import pytest

from geoproc.errors import UsageError
from geoproc.wos.closest import build_segment_grid, closest_points
from geoproc.wos.domain import build_domain
from geoproc.wos.expression import evaluate, parse_expression
from geoproc.wos.problem import WalkProblem, pass_seed
from geoproc.wos.solve import solve_laplace
from tests.conftest import load_fixture_module


def _load_wos_fixtures():
    """fixtures/wos_fixtures.py, loaded the way conftest loads make_fixtures."""
    return load_fixture_module("wos_fixtures")


wf = _load_wos_fixtures()
RE_Z3 = parse_expression("x**3 - 3*x*y**2")
DISK = build_domain(wf.disk(256)["loops"])
POINTS = np.array([[0.0, 0.0], [0.5, 0.2], [-0.3, -0.6], [0.85, -0.1], [-0.2, 0.93]])


def test_distance_lower_bound_in_cells_with_many_candidates():
    # a disk of 20,000 segments: the middle cells are crowded (more than BVH_ABOVE
    # candidates) and answer d* - |p - c| without a query, which must stay a lower
    # bound of the distance
    import numba

    from geoproc.wos.closest import distance_lower_bound

    d = build_domain(wf.disk(20_000)["loops"])
    grid = build_segment_grid(d.A, d.B)
    assert (grid[10] >= 0).any()
    P = np.random.default_rng(1).uniform(-0.99, 0.99, (4000, 2))
    P = P[np.linalg.norm(P, axis=1) < 0.99]
    exact = closest_points(P, d.A, d.B, grid)[0]
    lower = numba.njit(lambda P, grid: [distance_lower_bound(p[0], p[1], grid) for p in P])(P, grid)
    lower = np.array(lower)
    assert (lower <= exact).all()
    # the bound loses at most the point's offset from its cell's centre (and the margin)
    half = np.sqrt(0.5) / grid[2]
    assert (lower >= exact - 2 * half - 2 * grid[9]).all()
    far = np.linalg.norm(P, axis=1) < 0.5
    assert (exact[far] - lower[far] > 10 * grid[9]).mean() > 0.5  # most of the middle took the bound, not a scan


@pytest.mark.parametrize("offset", [1e6, 1e9])
def test_distance_lower_bound_far_from_the_origin(offset):
    # the single-precision scan's margin covered p - origin's rounding with 1e-9 |origin|,
    # a million times that rounding: 1e6 units from 0 the free disks shrank by 1e-3 of the
    # domain and walks took 27 % more steps; the bound must stay a bound
    import numba

    from geoproc.wos.closest import distance_lower_bound

    shift = np.array([offset, -2 * offset])
    d = build_domain([np.asarray(loop) + shift for loop in wf.disk(256)["loops"]])
    grid = build_segment_grid(d.A, d.B)
    P = np.random.default_rng(2).uniform(-0.99, 0.99, (4000, 2))
    P = P[np.linalg.norm(P, axis=1) < 0.99] + shift
    exact = closest_points(P, d.A, d.B, grid)[0]
    lower = np.array(numba.njit(lambda P, grid: [distance_lower_bound(p[0], p[1], grid) for p in P])(P, grid))
    assert (lower <= exact).all()
    assert grid[9] <= 1e-6 * 2.0 + 1e-11 * offset  # 2.2e-16 |origin| of rounding, with room to spare
    assert (exact - lower).max() <= 1e-5 + 3e-11 * offset


def test_walks_far_from_the_origin_take_as_many_steps():
    def steps(offset):
        sq = build_domain([[[offset, offset], [offset + 1, offset], [offset + 1, offset + 1], [offset, offset + 1]]])
        return solve_laplace(sq, parse_expression("1"), walks=64, grid=32, seed=1).metrics["mean_steps_per_walk"]

    assert steps(1e6) == pytest.approx(steps(0.0), rel=0.02)  # 8.59 both; 10.89 with the old margin


def test_closest_points_match_brute_force():
    d = build_domain(wf.square_with_holes(200)["loops"])
    rng = np.random.default_rng(0)
    P = rng.uniform(-1.5, 1.5, (3000, 2))  # some outside the grid: brute-force fallback
    dist, seg, t = closest_points(P, d.A, d.B, build_segment_grid(d.A, d.B))
    E = d.B - d.A
    W = P[:, None, :] - d.A[None]
    tt = np.clip((W * E).sum(-1) / (E * E).sum(-1), 0, 1)
    D = np.linalg.norm(W - tt[..., None] * E, axis=-1)
    np.testing.assert_allclose(dist, D.min(axis=1), rtol=0, atol=1e-12)
    Q = d.A[seg] + t[:, None] * E[seg]
    np.testing.assert_allclose(np.linalg.norm(P - Q, axis=1), dist, atol=1e-12)


def _seed_errors(problem, X, exact, walks, seeds, kernels=None, sigma=None):
    errs = np.array([problem.estimate(X, walks, pass_seed(s, 7), 0, kernels, sigma)[0] - exact
                     for s in range(seeds)])
    return errs.mean(axis=0), errs.std(axis=0, ddof=1) / np.sqrt(seeds)


def test_naive_walks_are_unbiased():
    pb = WalkProblem(DISK, RE_Z3, None, 1e-4)
    exact = evaluate(RE_Z3, POINTS[:, 0], POINTS[:, 1])
    mean, se = _seed_errors(pb, POINTS, exact, 256, 16)
    assert (np.abs(mean) <= 3 * se).all(), (mean, se)
    assert (se < 0.02).all()  # the check has teeth: 3 SE stays well below the data's range


def test_reported_variance_is_unbiased_with_few_walks():
    # with 4 walks the sample variance needs Bessel's factor 4/3: over 2000 points the mean
    # squared error of the 4-walk mean must match the mean reported variance / 4
    # (statistical spread of the ratio about 3 %; without the factor it reads 1.33)
    pb = WalkProblem(DISK, RE_Z3, None, 1e-4)
    rng = np.random.default_rng(8)
    r = 0.9 * np.sqrt(rng.random(2000))
    a = 2 * np.pi * rng.random(2000)
    X = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
    mean, var, _ = pb.estimate(X, 4, pass_seed(1, 7))
    err = mean - evaluate(RE_Z3, X[:, 0], X[:, 1])
    ratio = np.mean(err ** 2) / np.mean(var / 4)
    assert 0.88 < ratio < 1.12, ratio


def test_reported_variance_does_not_see_a_constant_in_the_data():
    # adding 1e8 to the boundary data moves every score by 1e8 and leaves their spread;
    # from plain sums, s2 / n - m^2 cancelled (the standard error read 0.107 for 0.024)
    X = POINTS
    _, var0, _ = WalkProblem(DISK, RE_Z3, None, 1e-4).estimate(X, 256, pass_seed(1, 7))
    shifted = parse_expression("1e8 + x**3 - 3*x*y**2")
    mean, var, _ = WalkProblem(DISK, shifted, None, 1e-4).estimate(X, 256, pass_seed(1, 7))
    assert (var0 > 0.01).all()
    np.testing.assert_allclose(var, var0, rtol=1e-5)


def test_both_walk_kernels_are_loaded_before_the_timed_passes():
    # a fresh interpreter, as a command run is; a run this small walks on one thread, yet
    # both kernels are loaded before its timed pass: the parallel one used to be loaded
    # inside the first timed pass of a larger run (steps per second read 3.0M for 11.7M)
    import subprocess
    import sys

    code = (
        "import numpy as np\n"
        "from geoproc.wos.domain import build_domain\n"
        "from geoproc.wos.expression import parse_expression\n"
        "from geoproc.wos.solve import solve_laplace\n"
        "from geoproc.wos import walk\n"
        "solve_laplace(build_domain([[[0, 0], [1, 0], [1, 1], [0, 1]]]), parse_expression('x'), grid=4, walks=2)\n"
        "print(len(walk.wos_dirichlet.signatures), len(walk.wos_dirichlet_serial.signatures))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1", "1"]


def test_control_variate_walks_are_unbiased():
    from geoproc.wos.fit import green_kernels

    pb = WalkProblem(DISK, RE_Z3, None, 1e-4)
    ks = green_kernels(DISK, 40, pb.distance)
    # a deliberately poor control variate (random coefficients) must not bias the estimate
    sigma = np.random.default_rng(5).standard_normal(ks.M) * 0.05
    exact = evaluate(RE_Z3, POINTS[:, 0], POINTS[:, 1])
    mean, se = _seed_errors(pb, POINTS, exact, 256, 16, ks, sigma)
    assert (np.abs(mean) <= 3 * se).all(), (mean, se)


@pytest.mark.parametrize("eps", [1e-2, 1e-4])
def test_walks_stop_within_epsilon_and_not_before(eps):
    # a point closer than epsilon to the boundary scores at once (no step); one farther
    # takes at least one step in every walk: walks that stopped at 10 epsilon had passed
    # every accuracy test (rmse 4x larger on the demo's glyph, within its 0.02 bar)
    pb = WalkProblem(DISK, RE_Z3, None, eps)
    A, B = DISK.A[0], DISK.B[0]
    mid, e = (A + B) / 2, B - A
    inward = np.array([-e[1], e[0]]) / np.linalg.norm(e)
    inward = inward if DISK.contains((mid + 0.1 * inward)[None])[0] else -inward
    s = np.array([0.5, 0.9, 1.1, 2.0, 9.0]) * eps
    X = mid + s[:, None] * inward
    np.testing.assert_allclose(pb.distance(X), s, rtol=1e-9)
    walks = 64
    _, _, steps = pb.estimate(X, walks, pass_seed(3, 7))
    assert steps[:2].tolist() == [0, 0]
    assert (steps[2:] >= walks).all(), steps


def test_npass_first_adam_step_moves_every_coefficient_by_the_learning_rate():
    # Adam's bias-corrected first step is lr * g / (|g| + 1e-8) in units of the fitted
    # control variate's spread: each coefficient (in the fit's scale, the constant
    # included) moves by lr times that spread against its gradient's sign; without the
    # bias correction it moved by 0.1 lr. The walks are replaced by the exact solution.
    from geoproc.wos.fit import green_kernels
    from geoproc.wos.kernels import kernel_matrix
    from geoproc.wos.npass import adam_refine

    pb = WalkProblem(DISK, RE_Z3, None, 1e-3)
    ks = green_kernels(DISK, 12, pb.distance)

    class Exact:
        def estimate(self, X, walks, seed, index0, kernels, sigma):
            return evaluate(RE_Z3, X[:, 0], X[:, 1]), np.zeros(len(X)), np.ones(len(X), dtype=np.int64)

    rng = np.random.default_rng(3)
    cand = 0.8 * (rng.random((200, 2)) - 0.5)
    sigma0, b0, scale = 0.1 * rng.standard_normal(ks.M), 0.2, rng.uniform(0.5, 2.0, ks.M)
    mu = kernel_matrix(cand, ks).mean(axis=0)
    lr = 0.01
    sigma, b, walks, _ = adam_refine(Exact(), ks, sigma0, b0, scale, cand, lambda it: pass_seed(1, it),
                                     steps=1, batch=64, walks=4, lr=lr)
    before = np.append(sigma0 * scale, b0 + sigma0 @ mu)
    after = np.append(sigma * scale, b + sigma @ mu)
    unit = np.std((kernel_matrix(cand, ks) - mu) @ sigma0)
    np.testing.assert_allclose(np.abs(after - before), lr * unit, rtol=1e-3)  # a gradient of 1e-5: 0.999 lr
    assert walks == 64 * 4


def test_error_points_are_those_farther_than_two_epsilon_from_the_boundary():
    # the unit square, 20 pixels a side: the distance to the boundary is min(x, 1-x, y, 1-y),
    # so with epsilon 0.03 the outermost ring of pixel centres (0.025 from a side) is left out
    sq = build_domain([np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)])
    res = solve_laplace(sq, parse_expression("x"), walks=2, grid=20, eps=0.03, exact=True, seed=1)
    c = (np.arange(20) + 0.5) / 20
    X, Y = np.meshgrid(c, c)
    far = np.minimum.reduce([X, 1 - X, Y, 1 - Y]) > 0.06
    assert res.metrics["error_points"] == far.sum() == 18 * 18
    assert np.array_equal(res.scored, far[::-1])  # rows from the top


def test_rmse_falls_like_inverse_sqrt_walks():
    walks = np.array([16, 64, 256])
    rmse = np.array([solve_laplace(DISK, RE_Z3, walks=int(w), grid=24, exact=True, seed=3)
                     .metrics["rmse"] for w in walks])
    slope = np.polyfit(np.log(walks), np.log(rmse), 1)[0]
    assert slope == pytest.approx(-0.5, abs=0.08), rmse


@pytest.mark.parametrize("k", [1e-3, 1e3])
def test_npass_result_scales_with_the_data(k):
    # Adam's steps were absolute, in the data's units: on the unit square with
    # k (x^2 - y^2), rmse / k was 0.0005 at k = 1, 0.35 at k = 1e-3 (ten times plain
    # walks') and the refinement did nothing at k = 1e9
    kw = dict(walks=32, grid=16, exact=True, seed=2, kernels=24, npass_steps=64, method="npass")
    one = solve_laplace(DISK, RE_Z3, **kw).metrics["rmse"]
    scaled = solve_laplace(DISK, parse_expression(f"{k!r} * (x**3 - 3*x*y**2)"), **kw).metrics["rmse"]
    assert scaled / k == pytest.approx(one, rel=1e-6)


def test_control_variates_reduce_rmse_on_disk_re_z3():
    kw = dict(walks=32, grid=32, exact=True, seed=11, kernels=40)
    rmse = {m: solve_laplace(DISK, RE_Z3, method=m, npass_steps=64, **kw).metrics["rmse"]
            for m in ("naive", "cv-green", "cv-angle", "npass")}
    assert rmse["cv-green"] < 0.2 * rmse["naive"], rmse
    assert rmse["cv-angle"] < 0.5 * rmse["naive"], rmse
    assert rmse["npass"] < 0.2 * rmse["naive"], rmse


@pytest.mark.parametrize("seed", [0, 1])
def test_a_control_variate_that_adds_variance_is_left_out(seed):
    # cv-angle's 80 kernels fitted at the 208 fit points of a 16 x 16 grid fit the walks' noise:
    # rmse 0.14 against 0.075 for plain walks; its variance is checked at the fit points first
    kw = dict(walks=64, grid=16, exact=True, seed=seed)
    naive = solve_laplace(DISK, RE_Z3, method="naive", **kw)
    angle = solve_laplace(DISK, RE_Z3, method="cv-angle", **kw)
    assert angle.metrics["control_variate_used"] is False and angle.metrics["control_variate_variance_ratio"] > 1
    assert np.array_equal(angle.U, naive.U, equal_nan=True)  # the residual pass ran plain walks
    green = solve_laplace(DISK, RE_Z3, method="cv-green", **kw)  # one that helps is kept
    assert green.metrics["control_variate_used"] is True and green.metrics["control_variate_variance_ratio"] < 0.1
    assert green.metrics["rmse"] < 0.2 * naive.metrics["rmse"]


def test_the_control_variate_check_with_one_fit_walk_and_constant_data():
    # one fit walk per point measures no spread: the check had read the plain variance as 0 and
    # left every such control variate out (cv-green on the disk: rmse 0.156 against 0.051)
    kw = dict(walks=16, grid=16, exact=True, seed=0)
    one = solve_laplace(DISK, RE_Z3, method="cv-green", fit_walks=1, **kw)
    assert one.metrics["control_variate_used"] is True and 0 < one.metrics["control_variate_variance_ratio"] < 0.5
    assert one.metrics["rmse"] < 0.5 * solve_laplace(DISK, RE_Z3, method="naive", **kw).metrics["rmse"]
    # constant data: plain walks have no spread, the control variate one of rounding (had read inf,
    # with a note blaming the fit)
    for value in ("3", "1e6", "0"):
        res = solve_laplace(DISK, parse_expression(value), method="cv-angle", walks=16, grid=16)
        assert res.metrics["control_variate_variance_ratio"] == 0.0 and res.metrics["control_variate_used"] is True


def test_seeds_a_half_range_apart_give_other_streams():
    # the seed was reduced modulo 2**63, so s and s + 2**63 (both accepted) repeated each other
    seeds = [0, 1 << 63, 5, (1 << 63) + 5, (1 << 64) - 1]
    assert len({int(pass_seed(s, 0)) for s in seeds}) == len(seeds)


@pytest.mark.parametrize("seed", [np.int64(3), np.int32(3), np.uint64(3)])
def test_numpy_integer_seeds_are_their_value(seed):
    # a seed drawn by rng.integers() is a numpy integer: its remainder by 2**64 overflowed
    assert pass_seed(seed, 7) == pass_seed(3, 7)


def test_same_seed_same_numbers_any_thread_count():
    pb = WalkProblem(build_domain(wf.glyph("a", 128)["loops"]), RE_Z3, None, 1e-3)
    from geoproc.wos.solve import grid_over

    P = grid_over(pb.domain, 12).points()
    X = P[pb.domain.contains(P)]
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        a = pb.estimate(X, 64, pass_seed(4, 2))
        numba.set_num_threads(max(2, before) if numba.config.NUMBA_NUM_THREADS > 1 else 1)
        b = pb.estimate(X, 64, pass_seed(4, 2))
    finally:
        numba.set_num_threads(before)
    c = pb.estimate(X, 64, pass_seed(5, 2))
    assert len(X) >= 40
    for u, v in zip(a, b, strict=True):
        assert np.array_equal(u, v)
    assert not np.array_equal(a[0], c[0])


def test_walks_in_short_calls_give_the_same_numbers(monkeypatch):
    # long runs are cut into calls of about CHUNK_WALKS walks, so that Ctrl-C is answered
    # within a call: every call stays near that size, and the numbers do not change
    import geoproc.wos.problem as wp

    pb = WalkProblem(build_domain(wf.glyph("a", 128)["loops"]), RE_Z3, None, 1e-3)
    from geoproc.wos.solve import grid_over

    P = grid_over(pb.domain, 12).points()
    X = P[pb.domain.contains(P)]
    whole = pb.estimate(X, 64, pass_seed(4, 2))
    calls, estimate = [], pb.estimate
    monkeypatch.setattr(pb, "estimate", lambda Y, walks, *a: calls.append(len(Y) * walks) or estimate(Y, walks, *a))
    monkeypatch.setattr(numba, "get_num_threads", lambda: 1)
    monkeypatch.setattr(wp, "CHUNK_WALKS", 200)
    fractions = []
    parts = pb.estimate_chunked(X, 64, pass_seed(4, 2), progress=fractions.append)
    for u, v in zip(whole, parts, strict=True):
        assert np.array_equal(u, v)
    assert max(calls) == 3 * 64 and sum(calls) == len(X) * 64 and fractions[-1] == 1.0
    # fewer walks than a point has: two points per thread and call, so that no thread idles
    monkeypatch.setattr(wp, "CHUNK_WALKS", 10)
    for threads in (1, 3):
        monkeypatch.setattr(numba, "get_num_threads", lambda t=threads: t)
        calls.clear()
        parts = pb.estimate_chunked(X, 64, pass_seed(4, 2))
        assert np.array_equal(whole[0], parts[0])
        assert set(calls[:-1]) == {2 * threads * 64} and 0 < calls[-1] <= 2 * threads * 64


def test_grid_points_on_the_boundary_take_the_boundary_value():
    # square with a square hole whose sides pass through pixel centers (grid 4 -> h = 0.25)
    d = build_domain([[[0, 0], [1, 0], [1, 1], [0, 1]],
                      [[0.375, 0.375], [0.625, 0.375], [0.625, 0.625], [0.375, 0.625]]])
    g = parse_expression("exp(x)*cos(y)")
    r = solve_laplace(d, g, walks=4, grid=4, exact=True, seed=0)
    ys, xs = np.mgrid[0:4, 0:4]
    X, Y = (xs + 0.5) * 0.25, 1 - (ys + 0.5) * 0.25
    in_hole = (X >= 0.375) & (X <= 0.625) & (Y >= 0.375) & (Y <= 0.625)
    on_hole = in_hole & (np.isin(X, [0.375, 0.625]) | np.isin(Y, [0.375, 0.625]))
    assert on_hole.sum() == 4
    np.testing.assert_allclose(r.U[on_hole], np.exp(X[on_hole]) * np.cos(Y[on_hole]), rtol=0, atol=1e-12)


def test_per_vertex_values_interpolate_linearly():
    loops = wf.star(96, 3, 0.25)["loops"]
    L = np.asarray(loops[0])
    d = build_domain(loops, values=[2 * L[:, 0] - L[:, 1] + 0.5])
    r = solve_laplace(d, None, walks=64, grid=20, seed=0, method="cv-green", kernels=24)
    gs = r.grid
    P = gs.points().reshape(gs.ny, gs.nx, 2)
    ok = np.isfinite(r.U)
    err = r.U[ok] - (2 * P[ok][:, 0] - P[ok][:, 1] + 0.5)
    assert np.sqrt(np.mean(err**2)) < 0.01


# ---- Neumann: Walk on Stars --------------------------------------------------

RECT = build_domain(wf.rectangle_neumann()["loops"], neumann_segments=[np.array([1, 0, 1, 0], bool)])
RECT_PTS = np.array([[0.3, 0.5], [1.0, 0.1], [1.7, 0.9], [1.0, 0.5]])


def test_silhouette_candidates_are_the_vertices_between_two_neumann_segments():
    from geoproc.wos.wost import silhouette_candidates

    outer = [[0, 0], [4, 0], [4, 4], [0, 4]]
    hole = [[1, 1], [1, 2], [2, 2], [2, 1]]
    tri = [[3, 3], [3.5, 3], [3, 3.5]]
    flags = [np.array([1, 1, 0, 1], bool), np.ones(4, bool), np.array([1, 0, 1], bool)]
    d = build_domain([outer, hole, tri], flags)
    U, V, W = silhouette_candidates(d.A, d.B, d.neumann, d.loop_of)
    expected = set()  # every loop vertex whose incoming and outgoing segments are Neumann, by brute force
    for k in range(3):
        seg = np.flatnonzero(d.loop_of == k)
        for p, q in zip(seg, np.roll(seg, -1), strict=True):
            if d.neumann[p] and d.neumann[q]:
                expected.add((tuple(d.A[p]), tuple(d.B[p]), tuple(d.B[q])))
    got = {(tuple(u), tuple(v), tuple(w)) for u, v, w in zip(U, V, W, strict=True)}
    assert got == expected and len(U) == len(expected) == 2 + 4 + 1


# flux = du/dn with the outward normal: (0, -1) at the bottom y = 0, (0, 1) at the top y = 1
@pytest.mark.parametrize("u,flux", [("x", None), ("y", "2*y - 1"), ("x*y - 0.5*x", "x*(2*y - 1)")])
def test_wost_rectangle_with_flux_is_unbiased(u, flux):
    g = parse_expression(u)
    h = parse_expression(flux) if flux else None
    pb = WalkProblem(RECT, g, h, 1e-3)
    exact = evaluate(g, RECT_PTS[:, 0], RECT_PTS[:, 1])
    mean, se = _seed_errors(pb, RECT_PTS, exact, 128, 12)
    assert (np.abs(mean) <= 3 * se + 2e-3).all(), (mean, se)  # + O(eps) shell bias
    assert (se < 0.05).all()


def test_wost_reflex_sector_zero_flux():
    dom = wf.reflex_sector(96)
    flags = np.zeros(len(dom["loops"][0]), bool)
    flags[[0, -1]] = True
    d = build_domain(dom["loops"], neumann_segments=[flags])
    g = parse_expression("-(x*x + y*y)**(1/3) * sin(2*atan2(y, x)/3)")
    pb = WalkProblem(d, g, None, 1e-3)
    X = np.array([[0.5, 0.0], [-0.3, 0.4], [-0.2, -0.5], [0.2, 0.7], [0.05, 0.02]])
    assert d.contains(X).all()
    exact = evaluate(g, X[:, 0], X[:, 1])
    mean, se = _seed_errors(pb, X, exact, 128, 12)
    assert (np.abs(mean) <= 3 * se + 2e-3).all(), (mean, se)


# a thin Neumann slot: from above, its lower side lies inside the star's ball but out of sight
SLOT = build_domain([[[-1, -1], [1, -1], [1, 1], [-1, 1]],
                     [[-0.6, -0.02], [0.6, -0.02], [0.6, 0.02], [-0.6, 0.02]]],
                    neumann_segments=[np.zeros(4, bool), np.ones(4, bool)])
# u = y: du/dn (outward from the domain, into the slot) is -1 on top, +1 below, 0 at the ends
SLOT_FLUX = "-(y/0.02)*(0.6 - abs(x))/(0.6 - abs(x) + 1e-300)"


def test_wost_counts_only_the_neumann_boundary_it_sees():
    g = parse_expression("y")
    pb = WalkProblem(SLOT, g, parse_expression(SLOT_FLUX), 1e-3)
    X = np.array([[0.0, 0.1], [0.3, 0.05], [-0.5, -0.08], [0.0, -0.3], [0.2, 0.5]])
    mean, se = _seed_errors(pb, X, X[:, 1], 64, 12)
    # sampling the hidden side too had put these 0.16 to 0.40 off (5 to 12 SE)
    assert (np.abs(mean) <= 3 * se + 2e-3).all(), (mean, se)
    assert (se < 0.04).all()


def test_wost_straight_walls_split_in_pieces_hide_nothing():
    # a diamond whose two Neumann walls (on y = x and y = 2 - x, each 20 collinear
    # pieces each) face a Dirichlet pair; u = y - x, du/dn = sqrt(2) (y - x - 1)
    # on both walls. The visibility test had taken rounding noise in the
    # intersection with the pieces between p and z for a hit: 0.011 to 0.018
    # too high (2.7 to 5.8 SE)
    n = 20
    L = [(k / n, k / n) for k in range(n)] + [(1.0, 1.0)] + [(-k / n, 2 - k / n) for k in range(n)] + [(-1.0, 1.0)]
    d = build_domain([np.array(L)], [np.array([1] * n + [0] + [1] * n + [0], bool)])
    pb = WalkProblem(d, parse_expression("y - x"), parse_expression("sqrt(2)*(y - x - 1)"), 1e-4)
    X = np.array([(0.25, 0.25), (0.3, 0.4), (0.4, 1.0)])
    mean, se = _seed_errors(pb, X, X[:, 1] - X[:, 0], 2000, 16)
    assert (np.abs(mean) <= 3 * se + 2e-3).all(), (mean, se)
    assert (se < 0.005).all()


def test_wost_points_on_a_neumann_wall_start_inside():
    # L-shape, u = x y, Neumann on the two edges at the reflex corner (1, 1):
    # flux x on y = 1 (outward +y), y on x = 1 (outward +x), both 'x*y' there
    d = build_domain([[[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]],
                     neumann_segments=[np.array([0, 0, 1, 1, 0, 0], bool)])
    g = parse_expression("x*y")
    pb = WalkProblem(d, g, parse_expression("x*y"), 1e-3)
    X = np.array([[1.0, 1.25], [1.25, 1.0], [1.5, 1.0], [1.0, 1.0], [1.0, 1.75]])  # on the walls
    mean, se = _seed_errors(pb, X, X[:, 0] * X[:, 1], 64, 12)
    # a walk started on the wall shot half its rays through it: 0.08 to 0.26 off (3 to 9 SE)
    assert (np.abs(mean) <= 3 * se + 2e-3).all(), (mean, se)
    assert (se < 0.05).all()


def test_wost_is_scale_free():
    # the ray's self-hit threshold was 1e-12 absolute: at this scale walks passed through walls
    s = 1e-12
    loops = [np.asarray(L, float) * s for L in wf.rectangle_neumann()["loops"]]
    d = build_domain(loops, neumann_segments=[np.array([1, 0, 1, 0], bool)])
    g = parse_expression("x*y/1e-24 - 0.5*x/1e-12")
    pb = WalkProblem(d, g, parse_expression("x*(2*y/1e-12 - 1)/1e-24"), 1e-3 * s)
    ref = WalkProblem(RECT, parse_expression("x*y - 0.5*x"), parse_expression("x*(2*y - 1)"), 1e-3)
    small = pb.estimate(RECT_PTS * s, 128, pass_seed(1, 0))
    unit = ref.estimate(RECT_PTS, 128, pass_seed(1, 0))
    np.testing.assert_allclose(small[0], unit[0], atol=1e-6)
    assert small[2].sum() == pytest.approx(unit[2].sum(), rel=0.01)


def test_a_zero_flux_expression_is_no_flux():
    # --neumann 0, the stated meaning of leaving it out, drew flux samples: other bytes, more
    # steps, twice the time
    from geoproc.wos.expression import is_zero

    assert is_zero(parse_expression("0")) and is_zero(parse_expression("-0.0*1"))
    assert not is_zero(parse_expression("0*x")) and not is_zero(parse_expression("1e-300"))
    g = parse_expression("y")
    kw = dict(walks=16, grid=12, seed=3)
    plain = solve_laplace(RECT, g, **kw)
    zero = solve_laplace(RECT, g, flux=parse_expression("0"), **kw)
    np.testing.assert_array_equal(plain.U, zero.U)
    assert plain.metrics["total_steps"] == zero.metrics["total_steps"]


def test_control_variate_on_mixed_problem():
    g = parse_expression("x*y - 0.5*x")
    h = parse_expression("x*(2*y - 1)")
    kw = dict(flux=h, walks=32, grid=24, exact=True, seed=2, kernels=40)
    naive = solve_laplace(RECT, g, **kw).metrics
    cv = solve_laplace(RECT, g, method="cv-green", **kw).metrics
    assert cv["rmse"] < 0.3 * naive["rmse"], (cv["rmse"], naive["rmse"])
    assert abs(cv["bias"]) < 3 * cv["rmse"] / np.sqrt(cv["error_points"]) + 2e-3


def test_npass_ends_at_its_averaged_iterate():
    # u = y on the rectangle with Neumann top and bottom: with a constant learning rate the last
    # Adam iterate kept moving with the batches' noise, and these seeds ended at rmse 0.010-0.014,
    # worse than cv-green (0.006-0.008); the mean of the second half's iterates ends at 0.001-0.0015
    kw = dict(flux=parse_expression("2*y - 1"), walks=64, grid=64, eps=1e-3, exact=True)
    for seed in (13, 16, 22):
        npass = solve_laplace(RECT, parse_expression("y"), method="npass", seed=seed, **kw).metrics["rmse"]
        cv = solve_laplace(RECT, parse_expression("y"), method="cv-green", seed=seed, **kw).metrics["rmse"]
        assert npass < min(0.004, 0.5 * cv), (seed, npass, cv)


def test_problem_level_usage_errors(tmp_path):
    from geoproc.errors import InputError, UsageError
    from geoproc.wos.domain import load_domain_json

    with pytest.raises(UsageError, match="marks no Neumann"):
        WalkProblem(DISK, RE_Z3, parse_expression("0"), 1e-3)
    with pytest.raises(UsageError, match="give --boundary"):
        WalkProblem(DISK, None, None, 1e-3)
    all_neumann = build_domain(wf.disk(16)["loops"], neumann_segments=[np.ones(16, bool)])
    with pytest.raises(InputError, match="every boundary segment is Neumann"):
        WalkProblem(all_neumann, RE_Z3, None, 1e-3)
    broken = tmp_path / "b.json"
    broken.write_text('{"loops": [[[0, 0], [1, 0]')
    with pytest.raises(InputError, match="not valid JSON"):
        load_domain_json(str(broken))
    with pytest.raises(UsageError, match="--method"):
        solve_laplace(DISK, RE_Z3, method="fast")


@pytest.mark.slow
def test_cv_green_beats_naive_on_every_generated_domain():
    for name, doc, fns in wf.domains(256):
        d = build_domain(doc["loops"])
        g = parse_expression(fns[0])
        kw = dict(walks=32, grid=24, exact=True, seed=4, kernels=40)
        naive = solve_laplace(d, g, **kw).metrics["rmse"]
        green = solve_laplace(d, g, method="cv-green", **kw).metrics["rmse"]
        assert green < 0.5 * naive, (name, green, naive)


@pytest.mark.parametrize("loops, neumann", [
    # a Neumann island inside a hole of a Dirichlet square
    ([[[0, 0], [1, 0], [1, 1], [0, 1]], [[0.2, 0.2], [0.8, 0.2], [0.8, 0.8], [0.2, 0.8]],
      [[0.35, 0.35], [0.65, 0.35], [0.65, 0.65], [0.35, 0.65]]], 2),
    # a second component, all Neumann
    ([[[0, 0], [0.4, 0], [0.4, 1], [0, 1]], [[0.6, 0], [1, 0], [1, 1], [0.6, 1]]], 1),
])
def test_a_part_with_only_neumann_segments_is_refused(loops, neumann):
    # u is not unique there; its walks ran to the step cap and scored another part's Dirichlet data
    from geoproc.errors import InputError

    flags = [np.full(len(L), k == neumann) for k, L in enumerate(loops)]
    d = build_domain([np.array(L, float) for L in loops], flags)
    with pytest.raises(InputError, match=f"bounded by loop {neumann} has only Neumann segments"):
        WalkProblem(d, parse_expression("x"), None, 1e-3)
    # with the Neumann data on the hole instead, every part keeps a Dirichlet segment
    flags = [np.full(len(L), k == 1) for k, L in enumerate(loops)]
    if len(loops) == 3:
        WalkProblem(build_domain([np.array(L, float) for L in loops], flags), parse_expression("x"), None, 1e-3)


def test_grid_points_on_every_neumann_edge_of_a_hole_are_solved():
    # the even-odd test is arbitrary exactly on an edge: the points on the hole's top
    # (Neumann) edge had been left NaN while those on its bottom edge were solved
    outer = [[0, 0], [4, 0], [4, 4], [0, 4]]
    hole = [[1.25, 1.25], [2.75, 1.25], [2.75, 2.75], [1.25, 2.75]]
    d = build_domain([np.asarray(outer, float), np.asarray(hole, float)],
                     neumann_segments=[np.zeros(4, bool), np.array([1, 0, 1, 0], bool)])
    r = solve_laplace(d, parse_expression("y"), flux=parse_expression("-(y - 2)/0.75"),
                      walks=256, grid=8, exact=True, seed=0)
    cx = (np.arange(8) + 0.5) / 2  # pixel centres (grid 8 over the 4 x 4 box)
    y = 4 - cx[:, None] + 0 * cx[None, :]
    x = cx[None, :] + 0 * cx[:, None]
    in_hole = (x > 1.25) & (x < 2.75) & (y > 1.25) & (y < 2.75)
    assert np.isfinite(r.U[~in_hole]).all() and np.isnan(r.U[in_hole]).all()
    edge = ((y == 1.25) | (y == 2.75)) & (x > 1.25) & (x < 2.75)  # both Neumann edges, 2 points each
    assert edge.sum() == 4
    assert (np.abs(r.U[edge] - y[edge]) <= 4 * r.stderr[edge] + 1e-3).all(), (r.U[edge], r.stderr[edge])


def test_png_puts_the_top_row_of_the_field_at_the_top():
    # u = y on a square: in the plot (left of the colour bar) viridis's high end (yellow) lies
    # above its low end (purple); an image flipped upside down had them the other way round
    import io

    import matplotlib.image

    from geoproc.wos.images import png_bytes

    n = 32
    y = 1 - (np.arange(n) + 0.5) / n  # row 0 at the top
    U = np.repeat(y[:, None], n, axis=1)
    img = matplotlib.image.imread(io.BytesIO(png_bytes(U, (0, 1, 0, 1), "u = y", contours=0)))[..., :3]
    plot = img[:, : int(0.6 * img.shape[1])]
    rows = np.arange(plot.shape[0])[:, None] * np.ones(plot.shape[1])
    yellow = (plot[..., 0] > 0.85) & (plot[..., 1] > 0.8) & (plot[..., 2] < 0.3)
    purple = (plot[..., 0] < 0.35) & (plot[..., 1] < 0.1) & (plot[..., 2] > 0.25)
    assert yellow.sum() > 100 and purple.sum() > 100
    assert rows[yellow].mean() < rows[purple].mean() - 0.3 * plot.shape[0]


def test_pictures_of_tall_domains_are_capped():
    # the picture's height grew with the domain's aspect: 300 times taller than wide made a
    # 600 x 128,000 pixel PNG (2 GB of memory)
    import io

    import matplotlib.image

    from geoproc.wos.images import png_bytes

    U = np.ones((3000, 10))
    img = matplotlib.image.imread(io.BytesIO(png_bytes(U, (0, 1, 0, 300), "tall", contours=0)))
    assert img.shape[:2] == (1200, 600)
    # a '$' in the title (the domain file's name) was read as matplotlib math: exit 3
    assert png_bytes(np.ones((4, 4)), (0, 1, 0, 1), "a$_$b.json: naive").startswith(b"\x89PNG")


@pytest.mark.parametrize("method", ["npass", "cv-green"])
def test_green_control_variate_is_scored_at_the_boundary_point(method):
    # with c taken at the walk's last position (E[c(p)] = c(x0) exactly) the estimate kept the
    # whole stopping bias of plain walks, hidden by the control variate's small standard error:
    # unit square, npass, 2048 walks, epsilon 1e-3: rmse 0.00042 against a mean standard error
    # of 0.00019; with c at the boundary point only the residual g - c is biased: 0.00019
    sq = build_domain([[[0, 0], [1, 0], [1, 1], [0, 1]]])
    res = solve_laplace(sq, parse_expression("x**3 - 3*x*y**2"), method=method, walks=2048, grid=16, eps=1e-3,
                        exact=True, seed=2)
    assert res.metrics["rmse"] < 1.5 * res.metrics["mean_standard_error"]


def test_mean_standard_error_is_over_the_scored_points():
    # points within 2 epsilon of the boundary, many with a standard error of 0 (walks that stop at once); the mean
    # had taken them in while rmse leaves them out (a 1 cm square: 112 of 256 points)
    sq = build_domain([[[0, 0], [0.01, 0], [0.01, 0.01], [0, 0.01]]])
    res = solve_laplace(sq, parse_expression("(x*x - y*y)*10000"), method="naive", walks=64, grid=16, eps=1e-3,
                        exact=True, seed=1)
    se = res.stderr[res.scored]
    assert res.metrics["error_points"] == len(se) < res.metrics["grid_points_inside"]
    assert res.metrics["mean_standard_error"] == pytest.approx(float(se.mean()), rel=1e-12)
    assert res.metrics["rms_standard_error"] == pytest.approx(float(np.sqrt(np.mean(se**2))), rel=1e-12)
    assert res.metrics["rms_standard_error"] > res.metrics["mean_standard_error"]


@pytest.mark.parametrize("method", ["naive", "cv-green", "cv-angle"])
def test_a_domain_far_from_the_origin_is_solved_as_at_the_origin(method):
    # positions 1e12 from the origin round to 1.2e-4: cv-angle, whose kernels jump by
    # 2 pi across their own segments, ended at rmse 0.25 for 0.02 at the origin, and at
    # 9e14 the Green centres rounded back onto the boundary (an internal error)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    kw = dict(method=method, walks=64, grid=8, exact=True, seed=1)
    home = solve_laplace(build_domain([square]), parse_expression("x+y"), **kw)
    far = solve_laplace(build_domain([square + 1e12]), parse_expression("(x-1e12)+(y-1e12)"), **kw)
    assert far.grid.x0 == pytest.approx(home.grid.x0 + 1e12, abs=1e-3)
    assert far.grid.y1 == pytest.approx(home.grid.y1 + 1e12, abs=1e-3)
    assert far.metrics["rmse"] == pytest.approx(home.metrics["rmse"], abs=1e-3)  # the same walks
    # at 9e14 the data itself, x - 9e14 in doubles, rounds to 0.125: it runs, and stays near
    far = solve_laplace(build_domain([square + 9e14]), parse_expression("(x-9e14)+(y-9e14)"), **kw)
    assert far.metrics["rmse"] < 0.3


def test_a_far_domain_is_named_in_its_own_coordinates_and_takes_the_deepest_expression():
    # its walks run moved to the origin: a message had named the moved point (-0.5, -0.5),
    # and an expression at the evaluator's full depth could not take the shift
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) + 1e6
    with pytest.raises(UsageError, match=r"first at x = 1e\+06, y = 1e\+06"):
        solve_laplace(build_domain([square]), parse_expression("log(x-1000000)"), walks=4, grid=8)
    deep = "0+(" * 31 + "y" + ")" * 31
    res = solve_laplace(build_domain([square + 9e14]), parse_expression(deep), method="cv-green", walks=16,
                        grid=8)
    assert np.isfinite(res.U[res.scored]).all()


def test_spread_points_is_farthest_point_sampling():
    # the compiled loop against the definition: each new point the first farthest from those chosen
    from geoproc.wos.fit import spread_points

    def farthest(C, n):
        chosen = [0]
        d = ((C - C[0]) ** 2).sum(axis=1)
        while len(chosen) < n:
            chosen.append(int(np.argmax(d)))
            d = np.minimum(d, ((C - C[chosen[-1]]) ** 2).sum(axis=1))
        return chosen

    rng = np.random.default_rng(0)
    x, y = np.meshgrid(np.arange(40) / 40, np.arange(30) / 30)  # a grid: many ties, the first one wins
    for C in (rng.random((3000, 2)) * 3 - 1, np.c_[x.ravel(), y.ravel()]):
        assert spread_points(C, 64).tolist() == farthest(C, 64)
    assert spread_points(C[:10], 64).tolist() == list(range(10))


@pytest.mark.parametrize("offset", [(0.0, 0.0), (1e12, -3e12)])
def test_the_report_places_the_grid_in_the_domains_coordinates(offset):
    # pixel (row, col) at (grid_left + (col + 0.5) h, grid_top - (row + 0.5) h): the value there
    # is the solution there (u = x + 2y, so every pixel checks its own place); no report had said
    ox, oy = offset
    sq = build_domain([[[ox, oy], [ox + 2.0, oy], [ox + 2.0, oy + 1.0], [ox, oy + 1.0]]])
    res = solve_laplace(sq, parse_expression(f"(x - {ox!r}) + 2*(y - {oy!r})"), method="naive", walks=4,
                        grid=8, eps=1e-4, seed=1, exact=True)
    m = res.metrics
    assert (m["grid_left"], m["grid_top"]) == (ox, oy + 1.0) and m["pixel_size"] == 0.25
    rows, cols = np.indices(res.U.shape)
    x = m["grid_left"] + (cols + 0.5) * m["pixel_size"] - ox
    y = m["grid_top"] - (rows + 0.5) * m["pixel_size"] - oy
    assert np.allclose(res.exact, x + 2 * y, rtol=0, atol=1e-12)  # the declared function at each pixel's centre


@pytest.mark.parametrize("w,h,n", [(3.0, 1.0, 16), (1.0, 3.0, 16), (1.0, 1.0, 16), (2.0, 1.0, 7), (1.0, 1e-3, 8)])
def test_grid_covers_the_whole_bounding_box(w, h, n):
    # rounded to the nearest count, a 3 x 1 box at n = 16 had 5 rows, covering 0.9375 of its height
    from geoproc.wos.solve import grid_over

    dom = build_domain([np.array([[0, 0], [w, 0], [w, h], [0, h]], float)])
    g = grid_over(dom, n)
    assert max(g.nx, g.ny) == n and g.h == pytest.approx(max(w, h) / n)
    left, top, right, bottom = g.x0, g.y1, g.x0 + g.nx * g.h, g.y1 - g.ny * g.h
    assert left <= 0 and right >= w and bottom <= 0 and top >= h
    assert g.nx * g.h - w < g.h and g.ny * g.h - h < g.h  # no whole pixel beyond the box
    assert left + right == pytest.approx(w) and top + bottom == pytest.approx(h)  # centred


def test_declared_mean_value_gap_tells_harmonic_functions_from_others():
    # the mean value property on circles of half the depth: analytic references, no walks
    from geoproc.wos.solve import declared_mean_value_gap

    rng = np.random.default_rng(0)
    X = rng.uniform(-0.7, 0.7, (500, 2))
    X = X[np.hypot(X[:, 0], X[:, 1]) < 0.7]
    depth = 1 - np.hypot(X[:, 0], X[:, 1])  # the unit disk
    gap = {e: declared_mean_value_gap(parse_expression(e), X, depth)
           for e in ("x**3 - 3*x*y**2", "exp(x)*cos(y)", "(x-1.5)/((x-1.5)**2 + y*y)", "x*x + y*y",
                     "log(sqrt((x-0.05)**2 + y*y))")}
    assert max(gap[e] for e in ("x**3 - 3*x*y**2", "exp(x)*cos(y)", "(x-1.5)/((x-1.5)**2 + y*y)")) < 1e-13, gap
    # x^2 + y^2: the circle's mean exceeds the centre's value by rho^2, rho = depth / 2
    expected = np.max((depth / 2) ** 2) / np.ptp(X[:, 0] ** 2 + X[:, 1] ** 2)
    assert gap["x*x + y*y"] == pytest.approx(expected, rel=1e-9)
    assert gap["log(sqrt((x-0.05)**2 + y*y))"] > 0.1  # a singular point inside the disk
    assert np.isnan(declared_mean_value_gap(parse_expression("x"), X[:0], depth[:0]))


def test_wost_flux_from_the_outward_normal_on_tilted_walls():
    # a square turned by 30 degrees, Neumann on two opposite sides, u = x y:
    # the flux is grad u . n = y nx + x ny, which no expression in x and y
    # alone gives on both walls; the walks are unbiased with it, and the
    # declared solution's flux gap is 0 (a wrong normal, y nx - x ny, is not)
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    R = np.array([[c, -s], [s, c]])
    P = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) @ R.T
    d = build_domain([P], [np.array([1, 0, 1, 0], bool)])
    g = parse_expression("x*y")
    h = parse_expression("y*nx + x*ny", "--neumann", normals=True)
    pb = WalkProblem(d, g, h, 1e-3)
    X = np.array([[0.0, 0.0], [0.5, 0.2], [-0.4, 0.6], [0.3, -0.7]])
    assert d.contains(X).all()
    mean, se = _seed_errors(pb, X, X[:, 0] * X[:, 1], 256, 12)
    assert (np.abs(mean) <= 3 * se + 2e-3).all(), (mean, se)
    assert (se < 0.03).all()
    zero = _seed_errors(WalkProblem(d, g, None, 1e-3), X, X[:, 0] * X[:, 1], 256, 12)[0]
    assert np.abs(zero).max() > 0.05  # the flux matters here: zero flux is far off
    from geoproc.wos.solve import declared_flux_gap

    wrong = parse_expression("y*nx - x*ny", "--neumann", normals=True)
    assert declared_flux_gap(g, h, d, 2 * np.sqrt(2), 2.0) < 1e-4
    assert declared_flux_gap(g, wrong, d, 2 * np.sqrt(2), 2.0) > 0.1


@pytest.mark.parametrize("size", [1e-100, 1e-160, 1e-200, 1e-300])
def test_a_loop_too_small_to_resolve_is_refused_however_small(size):
    # the span had been a norm, whose squares underflow below about 1e-154: smaller loops
    # passed, and their outward normals divided by zero
    from geoproc.errors import InputError

    square = [[-1, -1], [1, -1], [1, 1], [-1, 1]]
    with pytest.raises(InputError, match=r"loop 1 spans only .*, below 1e-15 \(rescale the domain\)"):
        build_domain([square, [[0, 0], [size, 0], [0, size]]])
