"""The discrete gradient of a vertex function by ProcessLowerStars.

Robins, Wood and Sheppard, "Theory and algorithms for constructing discrete
Morse complexes from grayscale digital images", IEEE TPAMI 33(8), 2011,
Algorithm 1, on the triangles of a surface mesh.

Cells are ordered by the total order of :func:`geoproc.morse.vertex_order`
(value, then index): a simplex's key is the ranks of its vertices sorted in
decreasing order, compared lexicographically. Every cell lies in the lower star
of its highest vertex; each lower star is processed on its own: the vertex is
paired with its lowest edge, then edges and triangles are paired greedily by
key (simple-homotopy expansions), and what cannot be paired is critical.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from geoproc.morse.complex import SurfaceComplex
from geoproc.morse.heap import heap_pop, heap_push
from geoproc.morse.order import vertex_order


@dataclass
class DiscreteGradient:
    """A discrete gradient vector field on a triangle mesh (Forman).

    Each cell is paired with at most one cofacet or facet; -1 means unpaired.

    Attributes
    ----------
    vertex_edge : (n,) int64 array
        Edge each vertex is paired with (the arrow v -> e).
    edge_vertex : (k,) int64 array
        Vertex each edge is paired with (inverse of ``vertex_edge``).
    edge_triangle : (k,) int64 array
        Triangle each edge is paired with (the arrow e -> t).
    triangle_edge : (m,) int64 array
        Edge each triangle is paired with.
    critical_vertices, critical_edges, critical_triangles : int64 arrays
        Indices of the unpaired cells, sorted.
    rank : (n,) int64 array
        The vertex order the gradient was built under.
    """

    vertex_edge: np.ndarray
    edge_vertex: np.ndarray
    edge_triangle: np.ndarray
    triangle_edge: np.ndarray
    critical_vertices: np.ndarray
    critical_edges: np.ndarray
    critical_triangles: np.ndarray
    rank: np.ndarray


@numba.njit(cache=True, inline="always")
def _in_lower_star(F, t, v, rank):
    rv = rank[v]
    for j in range(3):
        w = F[t, j]
        if w != v and rank[w] > rv:
            return False
    return True


@numba.njit(cache=True, inline="always")
def _triangle_key(F, t, v, rank, N1):
    a = -1
    b = -1
    for j in range(3):
        w = F[t, j]
        if w != v:
            r = rank[w]
            if a == -1:
                a = r
            elif r > a:
                b = a
                a = r
            else:
                b = r
    return a * N1 + b + 1


@numba.njit(cache=True, inline="always")
def _unpaired_faces(E, FE, t, v, done_e):
    """Number of edges of t through v not yet paired, and one of them."""
    cnt = 0
    last = -1
    for j in range(3):
        e = FE[t, j]
        if (E[e, 0] == v or E[e, 1] == v) and not done_e[e]:
            cnt += 1
            last = e
    return cnt, last


@numba.njit(cache=True)
def _process_lower_stars(F, E, FE, ET, adj_ptr, adj_nbr, adj_edge, rank):
    n = rank.shape[0]
    k = E.shape[0]
    m = F.shape[0]
    N1 = n + 1
    v_e = np.full(n, -1, np.int64)
    e_v = np.full(k, -1, np.int64)
    e_t = np.full(k, -1, np.int64)
    t_e = np.full(m, -1, np.int64)
    crit_v = np.zeros(n, np.bool_)
    crit_e = np.zeros(k, np.bool_)
    crit_t = np.zeros(m, np.bool_)
    done_e = np.zeros(k, np.bool_)
    done_t = np.zeros(m, np.bool_)
    maxdeg = 0
    for v in range(n):
        maxdeg = max(maxdeg, adj_ptr[v + 1] - adj_ptr[v])
    cap = 6 * maxdeg + 8
    k0 = np.empty(cap, np.int64)  # PQzero: edges and triangles, item t -> -(t + 1)
    i0 = np.empty(cap, np.int64)
    k1 = np.empty(cap, np.int64)  # PQone: triangles
    i1 = np.empty(cap, np.int64)
    for v in range(n):
        rv = rank[v]
        delta = -1
        best = n
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            r = rank[adj_nbr[j]]
            if r < rv and r < best:
                best = r
                delta = adj_edge[j]
        if delta == -1:
            crit_v[v] = True
            continue
        v_e[v] = delta
        e_v[delta] = v
        done_e[delta] = True
        s0 = 0
        s1 = 0
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            r = rank[adj_nbr[j]]
            e = adj_edge[j]
            if r < rv and e != delta:
                s0 = heap_push(k0, i0, s0, r * N1, e)
        for s in range(2):
            t = ET[delta, s]
            if t >= 0 and _in_lower_star(F, t, v, rank):
                c, _ = _unpaired_faces(E, FE, t, v, done_e)
                if c == 1:
                    s1 = heap_push(k1, i1, s1, _triangle_key(F, t, v, rank, N1), t)
        while s0 > 0 or s1 > 0:
            while s1 > 0:
                alpha, s1 = heap_pop(k1, i1, s1)
                if done_t[alpha]:
                    continue
                c, face = _unpaired_faces(E, FE, alpha, v, done_e)
                if c == 0:
                    s0 = heap_push(k0, i0, s0, _triangle_key(F, alpha, v, rank, N1), -(alpha + 1))
                else:
                    e_t[face] = alpha
                    t_e[alpha] = face
                    done_e[face] = True
                    done_t[alpha] = True
                    for s in range(2):
                        t = ET[face, s]
                        if t >= 0 and not done_t[t] and _in_lower_star(F, t, v, rank):
                            c2, _ = _unpaired_faces(E, FE, t, v, done_e)
                            if c2 == 1:
                                s1 = heap_push(k1, i1, s1, _triangle_key(F, t, v, rank, N1), t)
            if s0 > 0:
                gamma, s0 = heap_pop(k0, i0, s0)
                if gamma >= 0:
                    if done_e[gamma]:
                        continue
                    crit_e[gamma] = True
                    done_e[gamma] = True
                    for s in range(2):
                        t = ET[gamma, s]
                        if t >= 0 and not done_t[t] and _in_lower_star(F, t, v, rank):
                            c2, _ = _unpaired_faces(E, FE, t, v, done_e)
                            if c2 == 1:
                                s1 = heap_push(k1, i1, s1, _triangle_key(F, t, v, rank, N1), t)
                else:
                    t = -gamma - 1
                    if done_t[t]:
                        continue
                    crit_t[t] = True
                    done_t[t] = True
    return v_e, e_v, e_t, t_e, crit_v, crit_e, crit_t


def discrete_gradient(cx: SurfaceComplex, f: np.ndarray) -> DiscreteGradient:
    """ProcessLowerStars: a discrete gradient whose critical cells are those of f.

    Parameters
    ----------
    cx : SurfaceComplex
        The mesh's cells (a 2-manifold, possibly with boundary and several
        components).
    f : (n,) float array
        Vertex values; ties are broken by vertex index.

    Returns
    -------
    DiscreteGradient
        A gradient field (no closed V-path, see :func:`find_closed_vpath`) whose
        critical cells are the minima (dimension 0), saddles (dimension 1, a
        k-fold saddle vertex gives k critical edges) and maxima (dimension 2) of
        f, each named by its highest vertex.
    """
    _, rank = vertex_order(f)
    v_e, e_v, e_t, t_e, cv, ce, ct = _process_lower_stars(
        cx.F, cx.E, cx.FE, cx.ET, cx.adj_ptr, cx.adj_nbr, cx.adj_edge, rank
    )
    return DiscreteGradient(
        v_e, e_v, e_t, t_e, np.flatnonzero(cv), np.flatnonzero(ce), np.flatnonzero(ct), rank
    )
