"""Topological simplification checked with gudhi (diagrams and bottleneck
distance), known answers and the sup-norm bound."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from geoproc.mesh import load_mesh
from geoproc.morse import discrete_gradient, lower_star_persistence, simplify_function, surface_complex

gudhi = pytest.importorskip("gudhi")

from tests.geoproc.test_morse import gudhi_diagrams, mfx  # noqa: E402


def finite_pairs(d: np.ndarray, at_least: float = 0.0, strictly_positive: bool = False) -> np.ndarray:
    d = d[np.isfinite(d[:, 1])]
    p = d[:, 1] - d[:, 0]
    keep = (p > 0) if strictly_positive else (p >= at_least)
    return d[keep & (p >= at_least)]


def kept_saddle_vertices(F, f, g, P):
    """Highest vertices of f's kept saddle edges (pairs with persistence >= P and
    essential edges) and of g's critical edges, sorted, with multiplicity."""
    cx = surface_complex(F, len(f))
    pf, pg = lower_star_persistence(cx, f), lower_star_persistence(cx, g)
    pers0 = f[pf.edge_top[pf.min_saddle_edge]] - f[pf.min_vertex]
    pers1 = f[pf.triangle_top[pf.max_triangle]] - f[pf.edge_top[pf.saddle_edge]]
    kept = np.concatenate([pf.min_saddle_edge[pers0 >= P], pf.saddle_edge[pers1 >= P], pf.essential_edges])
    gg = discrete_gradient(cx, g)
    return sorted(pf.edge_top[kept].tolist()), sorted(pg.edge_top[gg.critical_edges].tolist())


def assert_kept_pairs(ref_f, ref_g, P, slack=0.0):
    """gudhi diagrams of f and g: g has exactly f's pairs with persistence >= P
    (as pairs of non-zero persistence; with P = 0, f's pairs of non-zero
    persistence), within bottleneck distance P/2 (+ slack), and the same
    essential classes."""
    for dim in (0, 1):
        big = finite_pairs(ref_f[dim], P, strictly_positive=P == 0)
        after = finite_pairs(ref_g[dim], strictly_positive=True)
        assert len(after) == len(big), dim
        if len(big):
            assert gudhi.bottleneck_distance(big, after) <= P / 2 * (1 + 1e-9) + slack
    for dim in range(3):  # essential classes stay
        assert np.isinf(ref_g[dim][:, 1]).sum() == np.isinf(ref_f[dim][:, 1]).sum()


def check_simplification(V, F, f, P, **kw):
    """The issue's checks, with gudhi computing both diagrams (``kw`` go to simplify_function)."""
    cx = surface_complex(F, len(V))
    s = simplify_function(cx, f, P, **kw)
    g = s.g
    assert len(np.unique(g)) == len(g)  # no ties
    ref_f = gudhi_diagrams(F, f)
    assert_kept_pairs(ref_f, gudhi_diagrams(F, g), P)
    # critical points of g: exactly the kept minima and maxima of f, as many
    # saddles as needed; sorting g by (value, index) finds them
    pf, pg = lower_star_persistence(cx, f), lower_star_persistence(cx, g)
    pers0 = f[pf.edge_top[pf.min_saddle_edge]] - f[pf.min_vertex]
    pers1 = f[pf.triangle_top[pf.max_triangle]] - f[pf.edge_top[pf.saddle_edge]]
    kept_min = set(pf.min_vertex[pers0 >= P].tolist()) | set(pf.essential_vertices.tolist())
    kept_max = set(pf.triangle_top[pf.max_triangle[pers1 >= P]].tolist()) | set(
        pf.triangle_top[pf.essential_triangles].tolist())
    gg = discrete_gradient(cx, g)
    assert set(gg.critical_vertices.tolist()) == kept_min
    assert set(pg.triangle_top[gg.critical_triangles].tolist()) == kept_max
    c = (len(gg.critical_vertices), len(gg.critical_edges), len(gg.critical_triangles))
    assert c[0] - c[1] + c[2] == cx.euler_characteristic
    assert s.pairs_kept == len(finite_pairs(ref_f[0], P)) + len(finite_pairs(ref_f[1], P))
    return s


def test_a_chain_that_drops_by_exactly_p_is_not_a_move_beyond_half(shared_data):
    # integer levels at P = 1: chains of f that drop by exactly P leave the box f +- P/2
    # no room for a strict order, and the construction widens it by 1e-9 of its size;
    # that had counted as 25 moves past P/2 (by 5e-10) and failed a --check on them
    m = load_mesh(shared_data / "meshes" / "fandisk.off")
    f = np.round(8 * m.V[:, 1] / np.ptp(m.V[:, 1])) + np.random.default_rng(0).integers(0, 2, len(m.V))
    s = simplify_function(surface_complex(m.F, len(m.V)), f.astype(np.float64), 1.0)
    assert 0.5 < s.max_abs_change <= 0.5 * (1 + 2e-9)
    assert len(s.widened_vertices) == 0


@pytest.mark.parametrize("P", [0.05, 0.5])
def test_noisy_sphere_within_half_threshold(make_fixtures, P):
    V, F = make_fixtures.icosphere(3)
    f = V[:, 2] + 0.1 * np.random.default_rng(1).standard_normal(len(V))
    s = check_simplification(V, F, f, P)
    assert s.max_abs_change <= P / 2 * (1 + 1e-12)
    assert len(s.widened_vertices) == 0
    # here every kept saddle also stays at its vertex, with its multiplicity
    cx = surface_complex(F, len(V))
    pf, pg = lower_star_persistence(cx, f), lower_star_persistence(cx, s.g)
    pers0 = f[pf.edge_top[pf.min_saddle_edge]] - f[pf.min_vertex]
    pers1 = f[pf.triangle_top[pf.max_triangle]] - f[pf.edge_top[pf.saddle_edge]]
    kept = np.concatenate([pf.min_saddle_edge[pers0 >= P], pf.saddle_edge[pers1 >= P], pf.essential_edges])
    gg = discrete_gradient(cx, s.g)
    assert sorted(pf.edge_top[kept].tolist()) == sorted(pg.edge_top[gg.critical_edges].tolist())


def test_noisy_sphere_down_to_one_minimum_one_maximum(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    f = V[:, 2] + 0.1 * np.random.default_rng(1).standard_normal(len(V))
    cx = surface_complex(F, len(V))
    before = discrete_gradient(cx, f)
    assert len(before.critical_vertices) > 20
    P = 3.0  # larger than every finite pair (the range of f is about 2.6)
    s = check_simplification(V, F, f, P)
    after = discrete_gradient(cx, s.g)
    assert (len(after.critical_vertices), len(after.critical_edges), len(after.critical_triangles)) == (1, 0, 1)
    assert after.critical_vertices[0] == np.argmin(f)
    assert s.max_abs_change <= P / 2


def test_open_disk_patch():
    V, F = mfx.disk_patch()
    r2 = ((V[:, :2] - 0.5) ** 2).sum(axis=1)
    f = -r2 + 0.01 * np.random.default_rng(7).standard_normal(len(V))
    s = check_simplification(V, F, f, 0.1)  # boundary notches make pairs up to ~0.05
    cx = surface_complex(F, len(V))
    after = discrete_gradient(cx, s.g)
    # the dome: one minimum, the boundary saddle, the top
    assert (len(after.critical_vertices), len(after.critical_edges), len(after.critical_triangles)) == (1, 1, 1)


def test_several_components():
    V, F = mfx.two_spheres()
    f = mfx.noisy_height(V, axis=2, noise=0.05, seed=8)
    check_simplification(V, F, f, 0.1 * (f.max() - f.min()))


def test_pairs_of_exactly_the_threshold_are_kept():
    # integer values: many pairs have a persistence of exactly P, and "everything
    # with persistence < P goes" must keep them (and count them as kept)
    V, F = mfx.two_spheres(2)
    f = np.random.default_rng(3).integers(0, 12, len(V)).astype(np.float64)
    ref = gudhi_diagrams(F, f)
    P = 3.0
    exact = sum(int(np.sum(np.isclose(d[np.isfinite(d[:, 1]), 1] - d[np.isfinite(d[:, 1]), 0], P))) for d in ref[:2])
    assert exact >= 3
    s = check_simplification(V, F, f, P)
    assert s.pairs_kept == len(finite_pairs(ref[0], P)) + len(finite_pairs(ref[1], P))


def test_threshold_zero_keeps_f():
    V, F = mfx.two_spheres(1)
    f = mfx.noisy_height(V, seed=9)
    cx = surface_complex(F, len(V))
    s = simplify_function(cx, f, 0.0)
    np.testing.assert_array_equal(s.g, f)
    assert s.pairs_removed == 0


# mesh, height axis, P / range, and what the exact windows reach: vertices beyond P/2, max |f - g| / P
# (without them: 4, 0.802; 9, 0.571; 8, 0.766; 2, 0.523; bunny's 0.802 is certified in test_morse_bound)
SHARED = [("bunny.off", 1, 0.01, 2, 0.8024), ("camelhead.off", 1, 0.05, 5, 0.5565),
          ("fertility.off", 2, 0.02, 4, 0.5610), ("spot.obj", 1, 0.05, 2, 0.5230)]


@pytest.mark.parametrize("name,axis,rel,beyond_max,change_max", SHARED)
def test_shared_meshes_noisy_height(shared_data, name, axis, rel, beyond_max, change_max):
    mesh = load_mesh(shared_data / "meshes" / name)
    f = mfx.noisy_height(mesh.V, axis=axis, noise=0.02, seed=10)
    P = rel * (f.max() - f.min())
    s = check_simplification(mesh.V, mesh.F, f, P)
    # sup-norm: P/2 except at a few vertices (see test_morse_bound for where it
    # is provably out of reach), and within P everywhere
    beyond = np.abs(s.g - f) > P / 2 * (1 + 1e-12)
    assert np.array_equal(np.flatnonzero(beyond), s.widened_vertices)
    assert beyond.sum() <= beyond_max
    assert s.max_abs_change <= change_max * P
    # every kept saddle at its own vertex, with its multiplicity
    want, have = kept_saddle_vertices(mesh.F, f, s.g, P)
    assert want == have


def test_all_exact_windows_reach_half_threshold(shared_data):
    """spot, height + 2% noise, P = 5%: two vertices beyond P/2 with the default
    windows (0.523 P); solving every window, wider where still beyond, reaches
    P/2, every check still holding and every kept saddle at its own vertex."""
    mesh = load_mesh(shared_data / "meshes" / "spot.obj")
    f = mfx.noisy_height(mesh.V, axis=1, noise=0.02, seed=10)
    P = 0.05 * (f.max() - f.min())
    s = check_simplification(mesh.V, mesh.F, f, P, exact_windows=-1)
    assert len(s.widened_vertices) == 0
    assert s.max_abs_change <= P / 2 * (1 + 1e-12)
    want, have = kept_saddle_vertices(mesh.F, f, s.g, P)
    assert want == have


def monkey_saddle_case():
    """A cancelled minimum m = 1 and maximum M = 4 meeting at the vertex s = 0,
    each with no other neighbour within P = 1 (hexagon fan around s, closed
    by an outer ring)."""
    ang = np.arange(6) * np.pi / 3
    V = np.concatenate([[[0, 0, 0]], np.c_[np.cos(ang), np.sin(ang), 0 * ang],
                        np.c_[2 * np.cos(ang + np.pi / 6), 2 * np.sin(ang + np.pi / 6), 0 * ang]])
    F = [[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)]
    F += [[1 + i, 7 + i, 1 + (i + 1) % 6] for i in range(6)]
    F += [[1 + (i + 1) % 6, 7 + i, 7 + (i + 1) % 6] for i in range(6)]
    # s = 0.6; ring: m (0.0), high, low, M (1.2), low, high; outer ring alternates
    f = np.array([0.6, 0.0, 1.9, 0.05, 1.2, 0.1, 1.95] + [2.0, 2.1, -0.5, -0.4, 2.2, 2.3])
    return V, np.array(F), f, 1.0


def test_monkey_saddle_limit_of_piecewise_linear_functions():
    """A cancelled minimum m and maximum M meeting at one vertex s, each with no
    other neighbour within P: no piecewise-linear g without them stays within
    P/2. The least max |f - g| is (f(M) - f(5)) / 2 = 0.55 P (M climbs over the
    raised low neighbour 5; test_morse_bound finds it with an exact program);
    draining m and M both across s, as the cancellation relation does, costs
    (f(M) - f(m)) / 2 = 0.6 P, and the exact window takes it to 0.55 P."""
    V, F, f, P = monkey_saddle_case()
    cx = surface_complex(F, len(V))
    pp = lower_star_persistence(cx, f)
    assert 1 in pp.min_vertex and pp.edge_top[pp.min_saddle_edge[pp.min_vertex == 1][0]] == 0
    at_s = pp.edge_top[pp.saddle_edge] == 0
    assert 4 in pp.triangle_top[pp.max_triangle[at_s]]  # (s, M), persistence 0.6 < P
    s = simplify_function(cx, f, P)
    crit = discrete_gradient(cx, s.g)
    top_g = lower_star_persistence(cx, s.g).triangle_top
    assert 1 not in crit.critical_vertices and 4 not in top_g[crit.critical_triangles]
    # the exact window reaches the least value, up to its 1e-5 P order margins
    assert s.max_abs_change >= (f[4] - f[5]) / 2 * (1 - 1e-9)
    assert s.max_abs_change <= (f[4] - f[5]) / 2 + 1e-4 * P
    # without it: draining both across s
    s0 = simplify_function(cx, f, P, exact_windows=0)
    assert s0.max_abs_change == pytest.approx((f[4] - f[1]) / 2, rel=1e-6)


def test_pipeline_relabelled_matches_direct(shared_data):
    from geoproc.morse import morse_simplify

    mesh = load_mesh(shared_data / "meshes" / "bunny.off")
    f = mfx.noisy_height(mesh.V, axis=1, noise=0.02, seed=11)
    P = 0.02 * (f.max() - f.min())
    cx = surface_complex(mesh.F, len(f))
    r = morse_simplify(mesh.F, f, P, exact_windows=0)
    direct = simplify_function(cx, f, P, exact_windows=0)
    # equal up to the last-place steps that separate ties (index order differs)
    np.testing.assert_allclose(r.g, direct.g, rtol=0, atol=1e-12 * (f.max() - f.min()))
    np.testing.assert_array_equal(np.sort(r.order[r.simplification.kept_minima]), direct.kept_minima)
    # the exact windows may pick another optimum under another numbering, not another max |f - g|
    r = morse_simplify(mesh.F, f, P)
    direct = simplify_function(cx, f, P)
    assert r.simplification.max_abs_change == pytest.approx(direct.max_abs_change, rel=1e-6)


def test_canonical_faces_forget_the_input_order():
    from geoproc.morse.complex import canonical_faces

    rng = np.random.default_rng(3)
    F = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2], [4, 2, 1]])
    shift = rng.integers(0, 3, len(F))  # each triangle's corners rotated by its own shift
    G = np.array([np.roll(f, k) for f, k in zip(F, shift, strict=True)])[rng.permutation(len(F))]
    C = canonical_faces(F)
    assert np.array_equal(canonical_faces(G), C)
    assert np.array_equal(canonical_faces(G[:, ::-1]), C)  # nor their winding
    assert (np.diff(C, axis=1) > 0).all() and (np.diff(C[:, 0]) >= 0).all()
    # the same triangles: each row one of F's, its corners sorted
    assert sorted(map(tuple, C)) == sorted(tuple(sorted(f)) for f in F)


def test_simplification_does_not_depend_on_the_face_order(shared_data):
    """bunny, a random field, P = half its range, every window solved exactly:
    HiGHS stops at its node limit, so the program's row and column order
    decided the result (up to 0.25 of the range at 8 vertices, with faces
    reordered or corners rotated) before the faces were put in canonical order."""
    from geoproc.morse import morse_simplify

    mesh = load_mesh(shared_data / "meshes" / "bunny.off")
    f = np.random.default_rng(7).random(len(mesh.V))
    P = 0.5 * (f.max() - f.min())
    rng = np.random.default_rng(1)
    g = morse_simplify(mesh.F, f, P, exact_windows=-1).g
    reordered = mesh.F[rng.permutation(len(mesh.F))]
    assert np.array_equal(morse_simplify(reordered, f, P, exact_windows=-1).g, g)
    assert np.array_equal(morse_simplify(np.roll(mesh.F, 1, axis=1), f, P, exact_windows=-1).g, g)
    # every face wound the other way (the canonical order had kept the winding: camelhead's
    # values moved by up to 0.42 of the range)
    assert np.array_equal(morse_simplify(mesh.F[:, ::-1], f, P, exact_windows=-1).g, g)


@pytest.mark.slow
@pytest.mark.parametrize("rel", [0.01, 0.05])
def test_armadillo_noisy_height(shared_data, rel):
    mesh = load_mesh(shared_data / "meshes" / "armadillo.obj")
    f = mfx.noisy_height(mesh.V, axis=1, noise=0.02, seed=0)
    P = rel * (f.max() - f.min())
    s = check_simplification(mesh.V, mesh.F, f, P)
    assert s.max_abs_change <= P * (1 + 1e-12)
    assert len(s.widened_vertices) <= 0.005 * len(f)
    # the exact windows (0.903 P and 0.767 P without them)
    assert s.max_abs_change <= {0.01: 0.8683, 0.05: 0.7128}[rel] * P
    # kept saddles: at most 0.2% (and 10) of the kept saddle edges at another vertex
    want, have = kept_saddle_vertices(mesh.F, f, s.g, P)
    assert len(have) == len(want)
    moved = len(want) - sum((Counter(want) & Counter(have)).values())
    assert moved <= max(10, 0.002 * len(want))


def test_bad_input_to_the_library_function_is_refused(make_fixtures):
    from geoproc.errors import InputError, UsageError
    from geoproc.morse import morse_simplify

    V, F = make_fixtures.icosphere(2)
    f = V[:, 2].copy()
    with pytest.raises(InputError, match="references vertex -1"):
        morse_simplify(np.r_[F, [[0, 1, -1]]], f, 0.2)
    fn = f.copy()
    fn[3] = np.nan
    with pytest.raises(InputError, match=r"field 'f' has 1 non-finite values \(first: vertex 3\)$"):
        morse_simplify(F, fn, 0.2)
    fn[3] = np.inf  # as geodesic writes where no source reaches: the message says what to do
    with pytest.raises(InputError, match="all [+]inf, as geodesic writes .* give a source on every connected part"):
        morse_simplify(F, fn, 0.2)
    for P in (float("nan"), -1.0):
        with pytest.raises(UsageError, match="threshold"):
            morse_simplify(F, f, P)
    assert np.array_equal(morse_simplify(F.tolist(), f.tolist(), 0.2).g, morse_simplify(F, f, 0.2).g)


def test_an_offset_of_the_field_changes_nothing(fixture_dir):
    import igl

    from geoproc.morse import morse_simplify

    mesh = load_mesh(fixture_dir / "torus.ply")
    V, F = igl.upsample(mesh.V, mesh.F)
    f = V[:, 1] + 0.02 * np.ptp(V[:, 1]) * np.random.default_rng(0).standard_normal(len(V))
    P = 0.01 * np.ptp(f)
    a, b = morse_simplify(F, f, P), morse_simplify(F, f + 1000.0, P)
    # values placed at f +- P/2 round by units in the last place of 1000, far above 1e-12 P: not beyond P/2
    assert len(b.simplification.widened_vertices) == len(a.simplification.widened_vertices) <= 5
    np.testing.assert_allclose(b.g - 1000.0, a.g, rtol=0, atol=1e-9 * P)


@pytest.mark.slow
def test_every_window_is_judged_by_the_half_bound(shared_data):
    """armadillo, height + 2% noise (seed 0), P = 5%, every window: a window's before/after
    comparison reused the name of the half-bound tolerance for its 1e-9 P closeness, so
    every window after the first counted vertices beyond 1e-9 P, not P/2 (146 left beyond
    P/2 instead of 142; about 40 s)."""
    from geoproc.morse import surface_complex
    from geoproc.morse.simplify import simplify_function

    mesh = load_mesh(shared_data / "meshes" / "armadillo.obj")
    h = mesh.V[:, 1]
    f = h + 0.02 * (h.max() - h.min()) * np.random.default_rng(0).standard_normal(len(h))
    s = simplify_function(surface_complex(mesh.F, len(f)), f, 0.05 * (f.max() - f.min()), exact_windows=-1)
    assert len(s.widened_vertices) <= 142


@pytest.mark.parametrize("barycentric", [False, True])
def test_simplification_summary_counts_match_gudhi(make_fixtures, barycentric):
    # the run's metrics from summary.py: Betti numbers, Euler characteristic and the pairs
    # removed and kept, against gudhi's diagrams of f; g's counts against gudhi's diagrams of g
    from geoproc.morse import barycentric_simplify, morse_simplify
    from geoproc.morse.summary import simplification_summary

    V, F = make_fixtures.torus(nu=24, nv=12)
    f = V[:, 0] + 0.3 * np.random.default_rng(5).random(len(V))
    P = 0.03  # 15 pairs of positive persistence, 0.014 to 0.093: some go, some stay
    res = barycentric_simplify(V, F, f, P) if barycentric else morse_simplify(F, f, P)
    s = simplification_summary(res, f, P)
    m = s.metrics
    ref = gudhi_diagrams(F, f)
    assert (m["betti_0"], m["betti_1"], m["betti_2"]) == tuple(int(np.isinf(d[:, 1]).sum()) for d in ref)
    assert m["euler_characteristic"] == 0
    pers = np.concatenate([d[np.isfinite(d[:, 1]), 1] - d[np.isfinite(d[:, 1]), 0] for d in ref[:2]])
    pers = pers[pers > 0]  # gudhi lists the zero-persistence pairs of the lower-star filtration too
    assert m["pairs_kept"] == int((pers >= P).sum()) and m["pairs_removed"] == int((pers < P).sum())
    assert m["pairs_kept"] >= 3 and m["pairs_removed"] >= 3
    ref_g = gudhi_diagrams(res.F if barycentric else F, s.g)
    pos = [int(((d[:, 1] > d[:, 0]) & np.isfinite(d[:, 1])).sum()) for d in ref_g[:2]]
    ess = [int(np.isinf(d[:, 1]).sum()) for d in ref_g]
    assert (m["minima_after"], m["saddles_after"], m["maxima_after"]) == (
        pos[0] + ess[0], pos[0] + pos[1] + ess[1], pos[1] + ess[2])
    assert m["minima_after"] - m["saddles_after"] + m["maxima_after"] == 0
    # many vertices sit at P/2 to rounding; none beyond it here, counted independently
    assert m["vertices_beyond_half_threshold"] == int((np.abs(s.g - s.f_ref) > P / 2 + 1e-12).sum()) == 0
    assert m["max_abs_change"] == pytest.approx(np.abs(s.g - s.f_ref).max())


def test_vertices_no_face_uses_are_no_cells_of_the_surface(make_fixtures):
    # kept under --no-clean, each had been an isolated component of the complex: an
    # essential minimum in every count, betti_0 and the Euler characteristic (a
    # tetrahedron with two such vertices read chi 4, betti_0 3), where info counts 2 and 1
    from geoproc.morse import morse_simplify
    from geoproc.morse.summary import simplification_summary

    V, F = make_fixtures.torus(nu=24, nv=12)
    f = V[:, 0] + 0.3 * np.random.default_rng(5).random(len(V))
    P = 0.03
    plain = morse_simplify(F, f, P)
    ref = simplification_summary(plain, f, P)
    # two stray vertices numbered first (every face index moves) and one last, with extreme values
    f2 = np.concatenate([[-5.0, 7.0], f, [-9.0]])
    res = morse_simplify(F + 2, f2, P)
    s = simplification_summary(res, f2, P)
    assert s.metrics == ref.metrics
    assert np.array_equal(res.g[2:-1], plain.g) and np.array_equal(res.g[[0, 1, -1]], [-5.0, 7.0, -9.0])
    assert np.array_equal(res.order, plain.order + 2)
    assert (s.metrics["euler_characteristic"], s.metrics["betti_0"]) == (0, 1)
    # the library's subdivision refuses them (the command leaves them out first); no faces at all
    # is refused too (it had raised ValueError from an empty reduction)
    from geoproc.errors import InputError
    from geoproc.morse import barycentric_simplify

    V2 = np.vstack([[[5.0, 5.0, 5.0]] * 2, V, [[9.0, 9.0, 9.0]]])
    with pytest.raises(InputError, match="3 vertices no face uses \\(first: 0\\)"):
        barycentric_simplify(V2, F + 2, f2, P)
    with pytest.raises(InputError, match="has no faces"):
        morse_simplify(np.zeros((0, 3), int), np.array([1.0, 2.0]), 0.1)


def test_simplification_summary_refuses_pairs_that_miss_the_gradient(make_fixtures):
    # a construction defect (pairs of another field) is an internal error, not a report
    from geoproc.morse import morse_simplify
    from geoproc.morse.summary import simplification_summary

    V, F = make_fixtures.torus(nu=24, nv=12)
    f = V[:, 0] + 0.3 * np.random.default_rng(5).random(len(V))
    res = morse_simplify(F, f, 0.25)
    res.pairs = lower_star_persistence(res.cx, np.random.default_rng(6).random(len(V)))
    with pytest.raises(RuntimeError, match="do not match"):
        simplification_summary(res, f, 0.25)


def test_simplified_field_follows_a_change_of_unit(make_fixtures):
    # g(s f) = s g(f) up to rounding: the local search compared costs with an absolute 1e-12,
    # which accepted rounding-level moves at s = 1e6 and refused real ones at 1e-6
    from tests.conftest import load_fixture_module

    V, F = make_fixtures.icosphere(4)
    cx = surface_complex(F, len(V))
    for seed in range(6):
        for axis in (0, 2):
            f = load_fixture_module("morse_fixtures").noisy_height(V, axis=axis, noise=0.05, seed=seed)
            P = 0.05 * np.ptp(f)
            g = simplify_function(cx, f, P, exact_windows=0).g
            for s in (1e-6, 1e6):
                scaled = simplify_function(cx, s * f, s * P, exact_windows=0).g / s
                assert np.abs(scaled - g).max() <= 1e-8 * np.ptp(f), (seed, axis, s)



def test_tie_allowances_count_each_vertex_its_own(make_fixtures):
    # each vertex's tie-breaking allowance is in the relabelled order of the simplification;
    # compared against the input's order, vertices got one another's (a plateau field offset by
    # 1e6 on a twice-looped torus: 1218 reported past P/2, 859 in truth)
    import igl

    from geoproc.morse import morse_simplify
    from geoproc.morse.summary import simplification_summary

    V, F = make_fixtures.torus()
    V, F = igl.loop(*igl.loop(V, F))
    y = (V[:, 1] - V[:, 1].min()) / np.ptp(V[:, 1])
    f = np.round(y + 0.05 * np.random.default_rng(0).standard_normal(len(V)), 1) + 1e6
    res = morse_simplify(F, f, 0.1)
    summary = simplification_summary(res, f, 0.1)
    assert summary.metrics["vertices_beyond_half_threshold"] == len(res.simplification.widened_vertices) > 0


@pytest.mark.parametrize("apex", ["minimum", "maximum", "middle"])
def test_a_vertex_of_high_valence_matches_gudhi(apex):
    # a fan of 300 triangles around one vertex: its lower edges and its edge bucket are sorted
    # by merge sort past 32 entries (insertion sort had made a 100k-face fan quadratic)
    from geoproc.morse import barycentric_simplify, morse_simplify
    from geoproc.morse.summary import simplification_summary

    N = 300
    t = 2 * np.pi * np.arange(N) / N
    V = np.vstack([[0.0, 0.0, 0.0], np.c_[np.cos(t), np.sin(t), 0.01 * np.sin(7 * t)]])
    F = np.c_[np.zeros(N, int), 1 + np.arange(N), 1 + (np.arange(N) + 1) % N]
    f = np.r_[0.0, np.sin(5 * t) + 0.3 * np.random.default_rng(4).standard_normal(N)]
    f[0] = {"minimum": f.min() - 1, "maximum": f.max() + 1, "middle": 0.05}[apex]
    ref = gudhi_diagrams(F, f)
    for res in (morse_simplify(F, f, 0.2), barycentric_simplify(V, F, f, 0.2)):
        s = simplification_summary(res, f, 0.2)
        pers = np.concatenate([finite_pairs(d, strictly_positive=True) for d in ref[:2]])
        pers = pers[:, 1] - pers[:, 0]
        m = s.metrics
        assert m["pairs_kept"] == int((pers >= 0.2).sum()) and m["pairs_removed"] == int((pers < 0.2).sum())
        assert m["betti_0"] == 1 and m["minima_after"] - m["saddles_after"] + m["maxima_after"] == 1
