"""Closest-point queries of Walk on Spheres: the segment hierarchy and the grid
built from it, against brute force over every segment."""

import numpy as np
import pytest

from geoproc.wos.closest import BVH_ABOVE, build_segment_grid, closest_points
from geoproc.wos.domain import build_domain
from geoproc.wos.segment_bvh import build_segment_bvh, bvh_closest_point, bvh_segments_within
from tests.conftest import load_fixture_module

wf = load_fixture_module("wos_fixtures")


def _brute_d2(P, A, B):
    """(p, s) squared distances with the queries' arithmetic (t = w.e / |e|^2, clipped)."""
    E = B - A
    W = P[:, None, :] - A[None]
    ee = E[:, 0] * E[:, 0] + E[:, 1] * E[:, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(ee > 0, (W[..., 0] * E[:, 0] + W[..., 1] * E[:, 1]) / ee, 0.0)
    t = np.clip(t, 0.0, 1.0)
    dx = W[..., 0] - t * E[:, 0]
    dy = W[..., 1] - t * E[:, 1]
    return dx * dx + dy * dy


def _segments(n, seed):
    rng = np.random.default_rng(seed)
    A = rng.uniform(-1, 1, (n, 2))
    B = A + rng.normal(0, 0.05, (n, 2))
    B[::17] = A[::17]  # zero-length segments
    A[5::23], B[5::23] = A[4::23][: len(A[5::23])], B[4::23][: len(A[5::23])]  # duplicates: exact ties
    return A, B


@pytest.mark.parametrize("n", [1, 3, 5, 200, 3000])
def test_nearest_segment_is_the_brute_force_one(n):
    A, B = _segments(n, n)
    nodes, leaf = build_segment_bvh(A, B, np.arange(n))
    P = np.random.default_rng(1).uniform(-1.5, 1.5, (400, 2))
    D = _brute_d2(P, A, B)
    for p, row in zip(P, D, strict=True):
        d2, s, _t = bvh_closest_point(p[0], p[1], nodes, leaf)
        assert d2 == row.min() and s == np.flatnonzero(row == row.min())[0]  # ties: the lowest index


def test_segments_within_a_radius_are_the_brute_force_ones():
    A, B = _segments(2000, 7)
    ids = np.arange(0, 2000, 3)  # a subset, as the grid over Dirichlet segments only
    nodes, leaf = build_segment_bvh(A, B, ids)
    P = np.random.default_rng(2).uniform(-1, 1, (200, 2))
    D = np.sqrt(_brute_d2(P, A[ids], B[ids]))
    out = np.empty(2001, dtype=np.int64)
    for p, row, r in zip(P, D, np.linspace(0.01, 0.4, len(P)), strict=True):
        n = bvh_segments_within(p[0], p[1], r, nodes, leaf, out, 2000)
        assert sorted(out[:n]) == sorted(ids[row <= r])
        want = int((row <= r).sum())
        assert bvh_segments_within(p[0], p[1], r, nodes, leaf, out, 10) == (want if want <= 10 else 11)


def test_grid_lists_are_those_of_testing_every_cell_against_every_segment():
    # the lists the build made by brute force before, entry for entry: the
    # benchmark and fixture domains keep their grids and their output bytes
    d = build_domain(wf.square_with_holes(200)["loops"])
    g = build_segment_grid(d.A, d.B)
    ox, oy, inv_cs, nx, ny, start, items = g[:7]
    assert (g[10] < 0).all()  # nothing crowded here
    cs = 1.0 / inv_cs
    c = np.arange(nx * ny)
    centres = np.column_stack([ox + (c % nx + 0.5) * cs, oy + (c // nx + 0.5) * cs])
    D = np.sqrt(_brute_d2(centres, d.A, d.B))
    best = D.min(axis=1)
    lim = best + 2.0 * (0.5 * cs * np.sqrt(2.0)) + 1e-12 * (1.0 + best)
    for k in range(nx * ny):
        assert items[start[k]:start[k + 1]].tolist() == np.flatnonzero(D[k] <= lim[k]).tolist()


def test_a_boundary_of_100000_segments_has_no_long_list_and_exact_queries():
    # the grid's capped resolution left cells near such a boundary listing
    # thousands of candidates, scanned at every step (140,000 steps/s against
    # 3 million with 1,000 segments); they now go to the hierarchy
    d = build_domain(wf.disk(100_000)["loops"])
    g = build_segment_grid(d.A, d.B)
    assert np.diff(g[5]).max() <= BVH_ABOVE and (g[10] >= 0).any()
    rng = np.random.default_rng(3)
    r, th = np.sqrt(rng.uniform(0, 1.2, 120)), rng.uniform(0, 2 * np.pi, 120)  # some outside the disk
    P = np.column_stack([r * np.cos(th), r * np.sin(th)])
    dist, seg, t = closest_points(P, d.A, d.B, g)
    D = _brute_d2(P, d.A, d.B)
    np.testing.assert_array_equal(dist, np.sqrt(D.min(axis=1)))
    np.testing.assert_array_equal(seg, D.argmin(axis=1))
