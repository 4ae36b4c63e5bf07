"""Discrete gradient, critical cells and lower-star persistence against
independent references: known answers and gudhi's lower-star persistence."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.mesh import load_mesh
from geoproc.morse import (
    DiscreteGradient,
    discrete_gradient,
    find_closed_vpath,
    lower_star_persistence,
    surface_complex,
    vertex_order,
)
from tests.conftest import load_fixture_module

gudhi = pytest.importorskip("gudhi")



def _fixtures():
    return load_fixture_module("morse_fixtures")


mfx = _fixtures()


def gudhi_diagrams(F: np.ndarray, f: np.ndarray) -> list[np.ndarray]:
    """Lower-star persistence by gudhi: every simplex at the max of its vertex
    values (vertices, then edges, then triangles inserted in batches)."""
    st = gudhi.SimplexTree()
    st.insert_batch(np.arange(len(f))[None, :], f)
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    st.insert_batch(E.T, f[E].max(axis=1))
    st.insert_batch(F.T, f[F].max(axis=1))
    st.compute_persistence(homology_coeff_field=2, min_persistence=-1, persistence_dim_max=True)
    return [st.persistence_intervals_in_dimension(d).reshape(-1, 2) for d in range(3)]


def positive(d: np.ndarray, at_least: float = 0.0) -> np.ndarray:
    """Pairs with persistence > 0 (and >= at_least), sorted rows."""
    p = d[:, 1] - d[:, 0]
    d = d[(p > 0) & (p >= at_least)]
    return d[np.lexsort((d[:, 1], d[:, 0]))]


def critical_sets(pp):
    c0 = set(pp.min_vertex.tolist()) | set(pp.essential_vertices.tolist())
    c1 = set(pp.min_saddle_edge.tolist()) | set(pp.saddle_edge.tolist()) | set(pp.essential_edges.tolist())
    c2 = set(pp.max_triangle.tolist()) | set(pp.essential_triangles.tolist())
    return c0, c1, c2


SHARED = [("bunny.off", 1), ("camelhead.off", 1), ("fertility.off", 2), ("spot.obj", 1)]


@pytest.mark.parametrize("name,axis", SHARED)
def test_pairs_match_gudhi_on_shared_meshes(shared_data, name, axis):
    mesh = load_mesh(shared_data / "meshes" / name)
    f = mfx.noisy_height(mesh.V, axis=axis, noise=0.02, seed=3)
    cx = surface_complex(mesh.F, len(mesh.V))
    pp = lower_star_persistence(cx, f)
    ref = gudhi_diagrams(mesh.F, f)
    P = 0.02 * (f.max() - f.min())
    for dim in range(3):
        ours, theirs = positive(pp.diagram(dim)), positive(ref[dim])
        assert ours.shape == theirs.shape, (name, dim)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=0)
        assert len(positive(pp.diagram(dim), P)) == len(positive(ref[dim], P))
    # Betti numbers (Z/2) from gudhi's essential classes
    assert pp.betti == tuple(int(np.isinf(ref[d][:, 1]).sum()) for d in range(3))


@pytest.mark.parametrize("name,axis", SHARED)
def test_gradient_is_acyclic_and_critical_cells_are_the_pairs(shared_data, name, axis):
    mesh = load_mesh(shared_data / "meshes" / name)
    f = mfx.noisy_height(mesh.V, axis=axis, noise=0.02, seed=4)
    cx = surface_complex(mesh.F, len(mesh.V))
    grad = discrete_gradient(cx, f)
    assert find_closed_vpath(cx, grad) is None
    c0, c1, c2 = critical_sets(lower_star_persistence(cx, f))
    assert set(grad.critical_vertices.tolist()) == c0
    assert set(grad.critical_edges.tolist()) == c1
    assert set(grad.critical_triangles.tolist()) == c2
    assert len(c0) - len(c1) + len(c2) == cx.euler_characteristic
    # every cell is critical or in exactly one pair
    paired_v = int((grad.vertex_edge >= 0).sum())
    paired_e = int((grad.edge_vertex >= 0).sum() + (grad.edge_triangle >= 0).sum())
    paired_t = int((grad.triangle_edge >= 0).sum())
    assert paired_v + len(c0) == cx.n
    assert paired_e + len(c1) == cx.n_edges
    assert paired_t + len(c2) == cx.n_faces


def test_closed_vpath_is_detected(make_fixtures):
    V, F = make_fixtures.grid(4)
    cx = surface_complex(F, len(V))
    f = V[:, 0] + 0.1 * V[:, 1]
    grad = discrete_gradient(cx, f)
    assert find_closed_vpath(cx, grad) is None
    # a vertex cycle 0 -> 1 -> 5 -> 4 -> 0 around one grid cell (n = 4)
    cyc = [0, 1, 5, 4]
    ve = np.full(cx.n, -1)
    ev = np.full(cx.n_edges, -1)
    for a, b in zip(cyc, cyc[1:] + cyc[:1], strict=True):
        e = int(np.flatnonzero((cx.E == sorted((a, b))).all(axis=1))[0])
        ve[a], ev[e] = e, a
    bad = DiscreteGradient(ve, ev, np.full(cx.n_edges, -1), np.full(cx.n_faces, -1),
                           np.array([]), np.array([]), np.array([]), grad.rank)
    found = find_closed_vpath(cx, bad)
    assert found is not None and found[0] == 0 and sorted(found[1]) == sorted(cyc)


def test_torus_height_has_one_minimum_two_saddles_one_maximum(make_fixtures):
    V, F = make_fixtures.torus()
    cx = surface_complex(F, len(V))
    f = V[:, 0]  # height across the axis; many ties, broken by vertex index
    grad = discrete_gradient(cx, f)
    assert (len(grad.critical_vertices), len(grad.critical_edges), len(grad.critical_triangles)) == (1, 2, 1)
    pp = lower_star_persistence(cx, f)
    assert pp.betti == (1, 2, 1)
    assert len(pp.min_vertex) == 0 and len(pp.saddle_edge) == 0
    assert f[pp.essential_vertices[0]] == f.min()
    assert f[pp.triangle_top[pp.essential_triangles[0]]] == f.max()


def test_ties_are_broken_by_index():
    order, rank = vertex_order(np.array([1.0, 0.0, 1.0, 0.0]))
    assert order.tolist() == [1, 3, 0, 2]
    assert rank.tolist() == [2, 0, 3, 1]


def finite(d: np.ndarray, at_least: float) -> int:
    return int(np.count_nonzero(np.isfinite(d[:, 1]) & (d[:, 1] - d[:, 0] >= at_least)))


def test_disk_patch_with_boundary_known_answers():
    V, F = mfx.disk_patch()
    cx = surface_complex(F, len(V))
    r2 = ((V[:, :2] - 0.5) ** 2).sum(axis=1)
    noise = 1e-3 * np.random.default_rng(5).standard_normal(len(V))
    # a bowl: one minimum, nothing else above the noise; a dome: the boundary
    # closes a loop (a saddle on the boundary) that the top fills (a maximum)
    for f, pairs0, pairs1 in [(r2 + noise, 0, 0), (-r2 + noise, 0, 1)]:
        pp = lower_star_persistence(cx, f)
        assert pp.betti == (1, 0, 0)
        assert (finite(pp.diagram(0), 0.05), finite(pp.diagram(1), 0.05)) == (pairs0, pairs1)
        ref = gudhi_diagrams(F, f)
        for dim in range(3):
            np.testing.assert_array_equal(positive(pp.diagram(dim)), positive(ref[dim]))


def test_several_components():
    V, F = mfx.two_spheres()
    f = mfx.noisy_height(V, axis=2, noise=0.05, seed=6)
    cx = surface_complex(F, len(V))
    pp = lower_star_persistence(cx, f)
    assert pp.betti == (2, 0, 2)
    ref = gudhi_diagrams(F, f)
    for dim in range(3):
        np.testing.assert_array_equal(positive(pp.diagram(dim)), positive(ref[dim]))


def test_npy_field_names_are_ascii_property_names():
    from geoproc.morse.fields import field_name

    # é.npy became the property '_' (and '__original'); accents are dropped now
    assert field_name("é.npy") == "e" and field_name("dist ance.npy") == "dist_ance"
    assert field_name("y.npy") == "y_value" and field_name("距离.npy") == "field"


@pytest.mark.parametrize("threshold", [0.5, 1e305, 1e307])
def test_diagram_band_drawn_at_any_threshold(make_fixtures, threshold):
    # the grey band below P vanished at P = 1e307: matplotlib's transform overflowed
    import io

    import matplotlib.image

    from geoproc.morse.diagram_plot import persistence_diagram_png

    V, F = make_fixtures.icosphere(2)
    f = np.random.default_rng(0).random(len(V))
    pp = lower_star_persistence(surface_complex(F, len(V)), f)
    img = matplotlib.image.imread(io.BytesIO(persistence_diagram_png(pp, pp, threshold)))
    band = np.all(np.abs(img[..., :3] - 0.85) < 0.01, axis=-1)  # the band's grey, 0.85
    assert band.mean() > 0.05, band.mean()
    # a '$' in the title (the file's name) was read as matplotlib math: exit 3
    assert persistence_diagram_png(pp, pp, threshold, title="a$_$b.ply").startswith(b"\x89PNG")


@pytest.mark.parametrize("lo, span", [(1.0e308, 0.7e308), (-8.9e307, 1.78e308)])
def test_diagram_drawn_for_values_near_the_float_range(make_fixtures, lo, span):
    # values accepted by the field check: the plot's margins overflowed to inf (exit 3,
    # "Axis limits cannot be NaN or Inf") and matplotlib's transform failed at a span of 1.78e308
    import io

    import matplotlib.image

    from geoproc.morse.diagram_plot import persistence_diagram_png

    V, F = make_fixtures.icosphere(2)
    f = lo + span * np.random.default_rng(0).random(len(V))
    pp = lower_star_persistence(surface_complex(F, len(V)), f)
    img = matplotlib.image.imread(io.BytesIO(persistence_diagram_png(pp, pp, 0.1 * span)))
    band = np.all(np.abs(img[..., :3] - 0.85) < 0.01, axis=-1)
    assert band.mean() > 0.02, band.mean()
    blue = np.all(np.abs(img[..., :3] - np.array([0.122, 0.467, 0.706])) < 0.02, axis=-1)  # tab:blue dots
    assert blue.sum() > 50, blue.sum()


def test_curvatures_of_a_sphere_approach_its_analytic_values():
    # a unit sphere has H = 1 / r = 1 and K = 1 / r^2 = 1; on the 2562-vertex icosphere libigl's
    # five-ring quadric fit reads H within 3 % (1.022-1.028; 1.005-1.008 on the 10242-vertex
    # one), the angle defect K within 0.2 %; both scale as 1 / length and 1 / length^2
    from geoproc.morse.fields import gaussian_curvature, mean_curvature

    V, F = load_fixture_module().icosphere(4)
    H, K = mean_curvature(V, F), gaussian_curvature(V, F)
    assert np.abs(H - 1).max() < 0.03 and np.abs(K - 1).max() < 0.002
    np.testing.assert_allclose(mean_curvature(2 * V, F), H / 2, rtol=1e-9)
    np.testing.assert_allclose(gaussian_curvature(2 * V, F), K / 4, rtol=1e-9)


def test_mean_curvature_does_not_depend_on_faces_stored_the_other_way_round():
    # libigl's quadric fit reads the sign from each face's winding: with 30 % of an
    # icosphere's faces reversed the mean curvature read from -7.3 to 4.5 for 1.10 to 1.12
    from geoproc.morse.fields import mean_curvature

    V, F = load_fixture_module().icosphere(3)
    H = mean_curvature(V, F)
    turned = np.random.default_rng(1).random(len(F)) < 0.3
    Fm = F.copy()
    Fm[turned] = Fm[turned][:, ::-1]
    np.testing.assert_allclose(mean_curvature(V, Fm), H, rtol=0, atol=1e-12)
    # all of them reversed: the file's winding (inwards) is kept, and the sign with it
    np.testing.assert_allclose(mean_curvature(V, F[:, ::-1]), -H, rtol=0, atol=1e-12)


def test_gaussian_curvature_on_a_boundary_follows_the_surface(make_fixtures):
    # the interior angle defect 2 pi - sum of angles gave the straight edge of a flat square
    # pi / area (2513 on the 21 x 21 grid) and its corners 3 pi / (2 area); a boundary vertex
    # now takes its interior neighbours' values: 0 on the plane, 1 on a unit sphere's cap
    from geoproc.mesh.topology import boundary_vertices
    from geoproc.morse.fields import gaussian_curvature

    V, F = make_fixtures.grid(21)
    assert np.abs(gaussian_curvature(V, F)).max() < 1e-9
    V, F = make_fixtures.icosphere(4)
    F = F[(V[F][:, :, 2] > 0.05).all(axis=1)]  # a cap with a jagged boundary
    K = gaussian_curvature(V, F)
    b = boundary_vertices(F)
    assert len(b) > 50 and np.abs(K[b] - 1).max() < 0.002
    # a grid patch of the unit sphere: two corners have no interior neighbour (they had read 0,
    # the field's lowest values); they take their boundary neighbours' values
    V, F = make_fixtures.grid(21)
    V = V - [0.5, 0.5, -1.0]
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    assert np.abs(gaussian_curvature(V, F) - 1).max() < 0.003


def test_gaussian_curvature_with_an_unused_vertex_stored_last():
    # libigl's mass matrix stops at the largest face index: --no-clean with a vertex no face
    # uses, stored last, failed to broadcast (exit 3)
    from geoproc.morse.fields import gaussian_curvature

    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [5, 5, 5.0]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    K = gaussian_curvature(V, F)
    assert K.shape == (5,) and K[4] == 0.0
    np.testing.assert_allclose(K[:4], gaussian_curvature(V[:4], F))
    # at the corner where three right angles meet the angle defect is pi/2
    import igl

    area = igl.massmatrix(V[:4], F, igl.MassMatrixType.MASSMATRIX_TYPE_VORONOI).diagonal()
    assert K[0] == pytest.approx((2 * np.pi - 3 * np.pi / 2) / area[0])


def test_a_subnormal_threshold_skips_the_windows_without_warnings():
    # the windows work in units of P: at P = 1e-320 the field's range overflows there,
    # and 25 lines of numpy warnings came with a successful run
    import warnings

    from geoproc.morse import morse_simplify

    V, F = load_fixture_module().torus()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = morse_simplify(F, V[:, 2].copy(), 1e-320)
    assert np.isfinite(res.g).all()
