"""Saddle-maximum persistence pairs by duality: union-find on the dual graph.

On a closed surface the 1-dimensional lower-star persistence pairs (edge,
triangle) are, with Z/2 coefficients, the 0-dimensional pairs of the dual
filtration: triangles are dual vertices, edges dual edges, both taken in
decreasing filtration order; when a dual edge merges two dual components the
younger one (whose highest triangle comes later in the filtration) dies, and
(edge, that triangle) is a saddle-maximum pair.

Boundary: every boundary loop is coned off by a virtual triangle fan with an
apex above every vertex. All cone triangles enter the reversed filtration
first and are joined by cone edges before any mesh edge, so they act as one
virtual dual vertex "outside" (index m) that is older than every triangle. A
component of triangles that reaches the boundary therefore dies when it merges
with the outside, and no finite pair involves the cone: the finite pairs of the
coned (closed) surface are exactly those of the mesh. Surfaces with several
components need nothing more.
"""

from __future__ import annotations

import numba
import numpy as np

from geoproc.union_find import find as _find


@numba.njit(cache=True)
def _triangle_keys(F, rank):
    m = F.shape[0]
    K = np.empty((m, 3), np.int64)
    for t in range(m):
        a, b, c = rank[F[t, 0]], rank[F[t, 1]], rank[F[t, 2]]
        if a < b:
            a, b = b, a
        if b < c:
            b, c = c, b
        if a < b:
            a, b = b, a
        K[t, 0], K[t, 1], K[t, 2] = a, b, c
    return K


@numba.njit(cache=True, inline="always")
def _older(K, m, s, t):
    """True when dual vertex s is older than t in the reversed filtration."""
    if s == m:
        return True
    if t == m:
        return False
    for j in range(3):
        if K[s, j] != K[t, j]:
            return K[s, j] > K[t, j]
    return False


@numba.njit(cache=True)
def dual_pairs(F, ET, adj_ptr, adj_nbr, adj_edge, order, rank):
    """Saddle-maximum pairs and essential 2-cells (see module docstring).

    Returns
    -------
    pair_edge : (p,) int64 array
        Edge of each pair (it creates a 1-cycle).
    pair_triangle : (p,) int64 array
        Triangle that fills it.
    killing : (k,) bool array
        Edges that kill a dual component (edges of a pair).
    essential : (c,) int64 array
        Highest triangle of each closed component (its 2-cycle never dies).
    """
    m = F.shape[0]
    k = ET.shape[0]
    K = _triangle_keys(F, rank)
    uf = np.arange(m + 1)
    size = np.ones(m + 1, np.int64)
    born = np.arange(m + 1)
    pe = np.empty(m, np.int64)
    pt = np.empty(m, np.int64)
    killing = np.zeros(k, np.bool_)
    p = 0
    maxdeg = 0
    n = order.shape[0]
    for v in range(n):
        maxdeg = max(maxdeg, adj_ptr[v + 1] - adj_ptr[v])
    br = np.empty(maxdeg + 1, np.int64)
    be = np.empty(maxdeg + 1, np.int64)
    for idx in range(n - 1, -1, -1):
        v = order[idx]
        rv = rank[v]
        c = 0
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            r = rank[adj_nbr[j]]
            if r < rv:  # lower edge; sort by decreasing rank of the other end
                i = c
                while i > 0 and br[i - 1] < r:
                    br[i] = br[i - 1]
                    be[i] = be[i - 1]
                    i -= 1
                br[i] = r
                be[i] = adj_edge[j]
                c += 1
        for i in range(c):
            e = be[i]
            t1 = ET[e, 0]
            t2 = ET[e, 1] if ET[e, 1] >= 0 else m
            r1 = _find(uf, t1)
            r2 = _find(uf, t2)
            if r1 == r2:
                continue
            if _older(K, m, born[r1], born[r2]):
                young, old = r2, r1
            else:
                young, old = r1, r2
            pe[p] = e
            pt[p] = born[young]
            killing[e] = True
            p += 1
            keep = born[old]
            if size[young] > size[old]:
                uf[old] = young
                size[young] += size[old]
                born[young] = keep
            else:
                uf[young] = old
                size[old] += size[young]
    outside = _find(uf, m)
    c = 0
    for t in range(m):
        if uf[t] == t and t != outside:
            c += 1
    ess = np.empty(c, np.int64)
    c = 0
    for t in range(m):
        if uf[t] == t and t != outside:
            ess[c] = born[t]
            c += 1
    return pe[:p].copy(), pt[:p].copy(), killing, ess
