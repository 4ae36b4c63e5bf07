"""The trees over the Neumann boundary (Walk on Stars) against scans of every
segment and silhouette vertex."""

from __future__ import annotations

import numpy as np

from geoproc.wos.domain import build_domain
from geoproc.wos.wost import (
    NEAR_LIMIT,
    _bvh_closest_silhouette_d2,
    _bvh_ray_hit,
    _near,
    closest_silhouette_d2,
    neumann_index,
    ray_hit,
    silhouette_candidates,
)


def _annulus_with_neumann_star(n=600):
    # a Dirichlet square around a Neumann star-shaped hole of n vertices: silhouettes
    # and reflex vertices all round
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.3 * np.cos(7 * t)
    hole = np.c_[r * np.cos(t), r * np.sin(t)][::-1]
    d = build_domain([[[-3, -3], [3, -3], [3, 3], [-3, 3]], hole])
    neumann = d.loop_of == 1
    return d, neumann


def test_trees_answer_as_the_scans():
    d, neumann = _annulus_with_neumann_star()
    A, B = np.ascontiguousarray(d.A), np.ascontiguousarray(d.B)
    nseg = np.flatnonzero(neumann).astype(np.int64)
    U, V, Wn = silhouette_candidates(A, B, neumann, d.loop_of)
    nodes_n, leaf_n, nodes_s, leaf_s = neumann_index(A, B, nseg, V)
    rng = np.random.default_rng(0)
    P = rng.uniform(-3, 3, (1500, 2))
    P = P[d.contains(P)]
    tiny = 1e-12 * 6 * np.sqrt(2)
    buf = np.empty(NEAR_LIMIT + 1, dtype=np.int64)
    E = B[nseg] - A[nseg]
    hits = 0
    for k, (px, py) in enumerate(P):
        limit2 = rng.uniform(0.01, 9.0)
        assert _bvh_closest_silhouette_d2(px, py, U, V, Wn, limit2, nodes_s, leaf_s) == \
            closest_silhouette_d2(px, py, U, V, Wn, limit2)
        # half the rays aimed at a vertex, where two segments tie
        if k % 2:
            th = rng.uniform(0, 2 * np.pi)
            dx, dy = np.cos(th), np.sin(th)
        else:
            q = A[nseg[rng.integers(len(nseg))]] - [px, py]
            dx, dy = q / np.linalg.norm(q)
        skip = int(nseg[k % len(nseg)]) if k % 3 == 0 else -1
        R = rng.uniform(0.1, 4.0)
        got = _bvh_ray_hit(px, py, dx, dy, R, A, B, skip, tiny, nodes_n, leaf_n)
        assert got == ray_hit(px, py, dx, dy, R, A, B, nseg, skip, tiny)
        hits += got[1] >= 0
        near = _near(px, py, R / 8, nseg, nodes_n, leaf_n, buf)
        w = np.array([px, py]) - A[nseg]
        t = np.clip(np.einsum("ij,ij->i", w, E) / np.einsum("ij,ij->i", E, E), 0, 1)
        dist = np.linalg.norm(w - t[:, None] * E, axis=1)
        assert set(near) >= set(nseg[dist <= R / 8 * (1 - 1e-9)]) and set(near) <= set(nseg[dist <= R / 8 * (1 + 1e-8)])
        assert np.all(np.diff(near) > 0)
    assert hits > len(P) // 4


def test_clip_to_disk_far_from_the_segment_start():
    # a long wall beside a small ball: |a - c|^2 - R^2 lost R^2 to rounding, and a
    # segment missing the disk by 1e-7 R got a piece of it
    from geoproc.wos.wost import _clip_to_disk

    R = 1e-8
    u0, u1 = _clip_to_disk(-1.0, R * (1 + 1e-7), 1.0, R * (1 + 1e-7), 0.0, 0.0, R)
    assert u1 <= u0
    h = 0.6 * R
    u0, u1 = _clip_to_disk(-1.0, h, 1.0, h, 0.0, 0.0, R)
    assert abs((u1 - u0) * 2.0 / (2 * np.sqrt(R * R - h * h)) - 1) < 1e-6
    # near the segment (the quadratic, as before) the same interval
    u0, u1 = _clip_to_disk(-1.0, 0.6, 1.0, 0.6, 0.0, 0.0, 1.0)
    assert abs(u0 - 0.1) < 1e-12 and abs(u1 - 0.9) < 1e-12
