"""Sublevel-set components of a vertex function by union-find over the edges in
filtration order, with the descent forest that drains each component into its
minimum; optionally cancels minimum-saddle pairs below a persistence
threshold by reversing the descent path (Forman's cancellation on the
vertex-edge gradient)."""

from __future__ import annotations

import numba
import numpy as np

from geoproc.union_find import find as _find


@numba.njit(cache=True)
def merge_forest(adj_ptr, adj_nbr, adj_edge, order, rank, value, threshold, cancel, keep):
    """0-dimensional lower-star persistence and the descent forest.

    Vertices are visited in ``order``; at vertex v its lower edges (neighbours
    of smaller rank) are taken by increasing rank of the neighbour: the
    lexicographic order of edges by (rank of the higher vertex, rank of the
    lower one), which is the lower-star filtration order. The first lower edge
    joins v to that neighbour's component (v's descent pointer); each later
    one either closes a cycle or merges two components, and the younger
    component (the one whose minimum has the larger rank) dies: a persistence
    pair (its minimum, v).

    Parameters
    ----------
    adj_ptr, adj_nbr, adj_edge : int64 arrays
        Vertex adjacency (CSR); ``adj_edge`` is the edge id (or -1 for an edge
        that is not a mesh edge, such as a cone edge).
    order : (N,) int64 array
        Vertices from first to last in the filtration.
    rank : (N,) int64 array
        Position of each vertex in ``order``.
    value : (N,) float64 array
        Filtration values (persistence = value of death - value of birth).
    threshold : float
        With ``cancel``, pairs of persistence < threshold are cancelled: the
        descent path from the dying component's side of the merging edge down
        to its minimum is reversed and continued across the edge, so the whole
        component drains into the surviving one.
    cancel : bool
        Whether to cancel pairs below ``threshold``.
    keep : (N,) bool array
        Minima never cancelled, whatever their persistence.

    Returns
    -------
    birth : (p,) int64 array
        Minimum of each dying component.
    death : (p,) int64 array
        Vertex at which it dies (the higher vertex of the merging edge).
    death_nbr : (p,) int64 array
        The other vertex of the merging edge.
    death_edge : (p,) int64 array
        The merging edge's id (from ``adj_edge``).
    down : (N,) int64 array
        Descent pointer of each vertex (-1 at the roots: the minima that stay).
    essential : (c,) int64 array
        Minimum of each component of the whole graph.
    first_edge : (N,) int64 array
        Edge id of each vertex's first lower edge (-1 for roots).
    """
    N = order.shape[0]
    uf = np.arange(N)
    size = np.ones(N, np.int64)
    born = np.arange(N)
    down = np.full(N, -1, np.int64)
    first_edge = np.full(N, -1, np.int64)
    birth = np.empty(N, np.int64)
    death = np.empty(N, np.int64)
    death_nbr = np.empty(N, np.int64)
    death_edge = np.empty(N, np.int64)
    p = 0
    maxdeg = 0
    for v in range(N):
        maxdeg = max(maxdeg, adj_ptr[v + 1] - adj_ptr[v])
    br = np.empty(maxdeg + 1, np.int64)
    bu = np.empty(maxdeg + 1, np.int64)
    be = np.empty(maxdeg + 1, np.int64)
    for v in order:
        rv = rank[v]
        c = 0
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            u = adj_nbr[j]
            if rank[u] < rv:
                br[c] = rank[u]
                bu[c] = u
                be[c] = adj_edge[j]
                c += 1
        if c == 0:
            continue
        # the lower edges by the neighbour's rank, stably: insertion sort, or a merge sort past
        # 32 (a minimum at the centre of a 100k-face fan had cost 9 s in insertion sort)
        if c > 32:
            srt = np.argsort(br[:c], kind="mergesort")
            br[:c], bu[:c], be[:c] = br[:c][srt], bu[:c][srt], be[:c][srt]
        else:
            for k in range(1, c):
                r, u, e = br[k], bu[k], be[k]
                i = k
                while i > 0 and br[i - 1] > r:
                    br[i] = br[i - 1]
                    bu[i] = bu[i - 1]
                    be[i] = be[i - 1]
                    i -= 1
                br[i] = r
                bu[i] = u
                be[i] = e
        u0 = bu[0]
        down[v] = u0
        first_edge[v] = be[0]
        r0 = _find(uf, u0)
        uf[v] = r0
        size[r0] += 1
        for i in range(1, c):
            u = bu[i]
            ru = _find(uf, u)
            rw = _find(uf, v)
            if ru == rw:
                continue
            if rank[born[ru]] < rank[born[rw]]:
                young, old, x, y = rw, ru, v, u
            else:
                young, old, x, y = ru, rw, u, v
            mn = born[young]
            birth[p] = mn
            death[p] = v
            death_nbr[p] = u
            death_edge[p] = be[i]
            p += 1
            if cancel and value[v] - value[mn] < threshold and not keep[mn]:
                prev = y
                cur = x
                while cur != -1:
                    nxt = down[cur]
                    down[cur] = prev
                    prev = cur
                    cur = nxt
            keep_birth = born[old]
            if size[young] > size[old]:
                uf[old] = young
                size[young] += size[old]
                born[young] = keep_birth
            else:
                uf[young] = old
                size[old] += size[young]
    c = 0
    for v in range(N):
        if uf[v] == v:
            c += 1
    essential = np.empty(c, np.int64)
    c = 0
    for v in range(N):
        if uf[v] == v:
            essential[c] = born[v]
            c += 1
    return birth[:p].copy(), death[:p].copy(), death_nbr[:p].copy(), death_edge[:p].copy(), down, \
        essential, first_edge


@numba.njit(cache=True)
def cone_adjacency(adj_ptr, adj_nbr, adj_edge, boundary):
    """Adjacency with one extra vertex (index n) joined to every boundary vertex.

    Coning off the boundary makes a surface with boundary behave like a closed
    one for superlevel-set components: the cone vertex is placed above every
    vertex, so a region touching the boundary is never a separate peak.
    Cone edges get edge id -1.
    """
    n = adj_ptr.shape[0] - 1
    nb = 0
    for v in range(n):
        if boundary[v]:
            nb += 1
    ptr = np.empty(n + 2, np.int64)
    ptr[0] = 0
    for v in range(n):
        ptr[v + 1] = ptr[v] + (adj_ptr[v + 1] - adj_ptr[v]) + (1 if boundary[v] else 0)
    ptr[n + 1] = ptr[n] + nb
    nbr = np.empty(ptr[n + 1], np.int64)
    eid = np.empty(ptr[n + 1], np.int64)
    c = ptr[n]
    for v in range(n):
        s = ptr[v]
        d = adj_ptr[v + 1] - adj_ptr[v]
        nbr[s:s + d] = adj_nbr[adj_ptr[v]:adj_ptr[v + 1]]
        eid[s:s + d] = adj_edge[adj_ptr[v]:adj_ptr[v + 1]]
        if boundary[v]:
            nbr[s + d] = n
            eid[s + d] = -1
            nbr[c] = v
            eid[c] = -1
            c += 1
    return ptr, nbr, eid
