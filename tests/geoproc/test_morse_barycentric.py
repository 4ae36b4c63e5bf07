"""Simplification on the barycentric subdivision: gudhi's diagrams of f (on the
mesh) and of g (on the subdivision), the sup-norm bound P/2 against the
lower-star extension computed here, and the critical vertices of g read off
its neighbourhoods."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.mesh import load_mesh
from geoproc.morse.barycentric import barycentric_simplify, subdivision_values

gudhi = pytest.importorskip("gudhi")

from tests.geoproc.test_morse import gudhi_diagrams, mfx  # noqa: E402
from tests.geoproc.test_morse_simplify import assert_kept_pairs  # noqa: E402


def lower_star_extension(F: np.ndarray, E: np.ndarray, f: np.ndarray) -> np.ndarray:
    """f on the subdivision's vertices: vertices, then edges, then triangles, each its largest vertex value."""
    return np.concatenate([f, f[E].max(axis=1), f[F].max(axis=1)])


def neighbours(F: np.ndarray, n: int) -> list[set]:
    nb = [set() for _ in range(n)]
    for a, b, c in F:
        nb[a] |= {b, c}
        nb[b] |= {a, c}
        nb[c] |= {a, b}
    return nb


def check_barycentric(V, F, f, P, slack=0.0):
    r = barycentric_simplify(V, F, f, P)
    n, k, m = len(V), len(r.E), len(F)
    assert r.V.shape == (n + k + m, 3) and r.F.shape == (6 * m, 3)
    # the edges are the mesh's, the subdivision vertices sit at the barycentres
    E_ref = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    np.testing.assert_array_equal(np.unique(r.E, axis=0), E_ref)
    np.testing.assert_allclose(r.V[n:n + k], V[r.E].mean(axis=1), atol=1e-12)
    np.testing.assert_allclose(r.V[n + k:], V[F].mean(axis=1), atol=1e-12)
    # every small triangle turns the way its parent does
    parent = np.repeat(np.arange(m), 6)
    small = np.cross(r.V[r.F[:, 1]] - r.V[r.F[:, 0]], r.V[r.F[:, 2]] - r.V[r.F[:, 0]])
    big = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])[parent]
    assert (np.einsum("ij,ij->i", small, big) > 0).all()
    # the bound, against f extended here
    fe = lower_star_extension(F, r.E, f)
    np.testing.assert_array_equal(r.f, fe)
    assert np.abs(r.g - fe).max() <= P / 2 * (1 + 1e-12) + slack
    assert len(np.unique(r.g)) == len(r.g)
    # gudhi: g keeps exactly the pairs of f with persistence >= P, within P/2
    assert_kept_pairs(gudhi_diagrams(F, f), gudhi_diagrams(r.F, r.g), P, slack)
    # minima and (interior) maxima of g, by comparing each vertex with its neighbours
    nb = neighbours(r.F, len(r.g))
    bnd = np.zeros(len(r.g), bool)
    e_sd = np.sort(np.concatenate([r.F[:, [0, 1]], r.F[:, [1, 2]], r.F[:, [2, 0]]]), axis=1)
    e_sd, count = np.unique(e_sd, axis=0, return_counts=True)
    bnd[e_sd[count == 1].ravel()] = True
    minima = {v for v in range(len(r.g)) if all(r.g[u] > r.g[v] for u in nb[v])}
    maxima = {v for v in range(len(r.g)) if not bnd[v] and all(r.g[u] < r.g[v] for u in nb[v])}
    crit = set(r.critical.tolist())
    assert minima == {v for v in crit if r.dim[v] == 0}
    assert maxima == {v for v in crit if r.dim[v] == 2}
    return r


def test_noisy_sphere(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    f = V[:, 2] + 0.1 * np.random.default_rng(1).standard_normal(len(V))
    r = check_barycentric(V, F, f, 0.3)
    assert r.pairs_removed > 10


def test_noisy_sphere_down_to_one_minimum_one_maximum(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    f = V[:, 2] + 0.1 * np.random.default_rng(1).standard_normal(len(V))
    r = check_barycentric(V, F, f, 3.0)  # above every finite pair
    assert len(r.critical) == 2
    assert r.critical[0] == np.argmin(f) and r.dim[r.critical[1]] == 2


def test_torus_height_and_noise(make_fixtures):
    V, F = make_fixtures.torus()
    f = V[:, 0] + 0.05 * np.random.default_rng(3).standard_normal(len(V))
    r = check_barycentric(V, F, f, 0.5)
    # height across a torus standing on its side: 1 minimum, 2 saddles, 1 maximum
    assert np.bincount(r.dim[r.critical], minlength=3).tolist() == [1, 2, 1]


def test_open_disk_patch():
    V, F = mfx.disk_patch()
    r2 = ((V[:, :2] - 0.5) ** 2).sum(axis=1)
    f = -r2 + 0.01 * np.random.default_rng(7).standard_normal(len(V))
    check_barycentric(V, F, f, 0.1)


def test_other_fields_are_interpolated_onto_the_subdivision():
    V, F = mfx.disk_patch()
    f = -((V[:, :2] - 0.5) ** 2).sum(axis=1)
    res = barycentric_simplify(V, F, f, 0.1)
    A = np.array([[1.0, -2.0], [0.5, 3.0], [2.0, 0.25]])
    fields = V @ A  # two linear fields: exact at midpoints and centroids
    np.testing.assert_allclose(subdivision_values(res, F, fields), res.V @ A, atol=1e-12)
    np.testing.assert_allclose(subdivision_values(res, F, fields[:, 0]), res.V @ A[:, 0], atol=1e-12)


def test_several_components():
    V, F = mfx.two_spheres()
    f = mfx.noisy_height(V, axis=2, noise=0.05, seed=8)
    check_barycentric(V, F, f, 0.1 * (f.max() - f.min()))


# where the vertex construction cannot reach P/2 (bunny: certified 0.802 P in test_morse_bound)
@pytest.mark.parametrize("name,axis,rel,seed", [("bunny.off", 1, 0.01, 10), ("fertility.off", 2, 0.02, 10),
                                                ("camelhead.off", 1, 0.05, 10)])
def test_shared_meshes_reach_half_threshold(shared_data, name, axis, rel, seed):
    mesh = load_mesh(shared_data / "meshes" / name)
    h = mesh.V[:, axis]
    f = h + 0.02 * (h.max() - h.min()) * np.random.default_rng(seed).standard_normal(len(h))
    check_barycentric(mesh.V, mesh.F, f, rel * (f.max() - f.min()))


def test_plateaus_of_tied_values_stay_within_the_bound(make_fixtures):
    # values rounded to 0.05: plateaus of equal values everywhere (ties broken by index)
    V, F = make_fixtures.icosphere(4)
    f = np.round(V[:, 2] + 0.2 * np.random.default_rng(4).standard_normal(len(V)), 1) / 2
    assert len(np.unique(f)) < len(f) / 50
    check_barycentric(V, F, f, 0.2)


def test_armadillo_height_with_ties(shared_data):
    # 1,284 repeated heights; breaking the ties of a plateau that sits at f + P/2
    # once took 3 cells 6.5e-14 beyond the bound
    mesh = load_mesh(shared_data / "meshes" / "armadillo.obj")
    f = mesh.V[:, 1]
    assert len(np.unique(f)) < len(f)
    r = barycentric_simplify(mesh.V, mesh.F, f, 0.05 * (f.max() - f.min()))
    fe = lower_star_extension(mesh.F, r.E, f)
    assert np.abs(r.g - fe).max() <= r.threshold / 2


def test_threshold_zero_gives_the_lower_star_extension(make_fixtures):
    # g is f on the cells, its ties (a cell and its highest vertex) broken by a
    # few units in the last place along the gradient: its critical points are
    # the critical cells (by index, every vertex sat below its star: a minimum)
    V, F = make_fixtures.icosphere(2)
    f = V[:, 2] + 0.1 * np.random.default_rng(5).standard_normal(len(V))
    r = check_barycentric(V, F, f, 0.0, slack=1e-13)
    assert r.pairs_removed == 0 and 0 < r.max_abs_change < 1e-13


@pytest.mark.parametrize("P", [0.0, 0.5])
@pytest.mark.parametrize("value", [0.0, 1.0])
def test_constant_field_has_one_minimum(make_fixtures, P, value):
    # a disk: one minimum, no saddle, no maximum, before and after (every
    # cell was critical with P = 0 when the ties went by index)
    V, F = make_fixtures.grid(8)
    r = check_barycentric(V, F, np.full(len(V), value), P, slack=1e-12)
    assert len(r.critical) == 1 and r.dim[r.critical[0]] == 0


def test_subdivision_values_keep_the_stored_type():
    # uchar colours averaged onto the subdivision had come back as float64 fractions
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.2]], float)
    F = np.array([[0, 1, 2], [1, 3, 2]])
    res = barycentric_simplify(V, F, V[:, 0] + 0.1 * V[:, 1], 0.0)
    red = np.array([0, 255, 100, 7], np.uint8)
    got = subdivision_values(res, F, red)
    assert got.dtype == np.uint8 and got[:4].tolist() == red.tolist()
    expected = np.rint(subdivision_values(res, F, red.astype(float)))  # the float means, rounded
    assert got.tolist() == expected.tolist() and 128 in got.tolist()  # (0 + 255) / 2 = 127.5 -> 128
    q = np.array([0.1, 0.2, 0.3, 0.4], np.float32)
    assert subdivision_values(res, F, q).dtype == np.float32
    assert subdivision_values(res, F, q.astype(float)).dtype == np.float64
