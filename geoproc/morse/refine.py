"""Vertex types of a piecewise-linear function and a local search that moves
single vertex values until every vertex has a wanted type, as close to f as
the types allow.

The type of a vertex v under g (vertices compared by (value, index)) depends
only on which neighbours are below it. With L lower neighbours out of d and
T incident triangles whose two other vertices are both lower:

- L = 0: a minimum (code -1);
- L = d at an interior vertex: a maximum (code -2);
- otherwise the lower link has L - T components (a union of paths of the link
  cycle, or of the link path at a boundary vertex) and v is a saddle of
  multiplicity L - T - 1 (code L - T - 1, 0 for a regular vertex).

These are exactly the critical cells ProcessLowerStars finds in v's lower star
(the reduced homology of the lower link; a boundary vertex is coned off by a
vertex above every value, so it is never a maximum).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def vertex_faces(F, n):
    """Triangles around each vertex in CSR form: ``vf_tri[vf_ptr[v]:vf_ptr[v + 1]]``."""
    cnt = np.zeros(n + 1, np.int64)
    for t in range(F.shape[0]):
        for j in range(3):
            cnt[F[t, j] + 1] += 1
    ptr = np.cumsum(cnt)
    pos = ptr[:-1].copy()
    tri = np.empty(ptr[n], np.int64)
    for t in range(F.shape[0]):
        for j in range(3):
            v = F[t, j]
            tri[pos[v]] = t
            pos[v] += 1
    return ptr, tri


@numba.njit(cache=True, inline="always")
def _below(g, w, v):
    return g[w] < g[v] or (g[w] == g[v] and w < v)


@numba.njit(cache=True)
def vertex_type(v, g, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary):
    """Type code of vertex v under g: -1 minimum, -2 maximum, k >= 0 saddle of
    multiplicity k (0: regular). Isolated vertices are minima."""
    d = adj_ptr[v + 1] - adj_ptr[v]
    low = 0
    for j in range(adj_ptr[v], adj_ptr[v + 1]):
        if _below(g, adj_nbr[j], v):
            low += 1
    if low == 0:
        return -1
    if low == d and not boundary[v]:
        return -2
    both = 0
    for j in range(vf_ptr[v], vf_ptr[v + 1]):
        t = vf_tri[j]
        c = 0
        for i in range(3):
            w = F[t, i]
            if w != v and _below(g, w, v):
                c += 1
        if c == 2:
            both += 1
    return low - both - 1


@numba.njit(cache=True)
def vertex_types(g, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary):
    """:func:`vertex_type` of every vertex."""
    n = g.shape[0]
    out = np.empty(n, np.int64)
    for v in range(n):
        out[v] = vertex_type(v, g, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary)
    return out


@numba.njit(cache=True)
def _mismatch(w, g, want, weight, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary):
    t = vertex_type(w, g, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary)
    if t == want[w]:
        return 0.0
    if t < 0 or want[w] < 0:  # a wrong minimum or maximum: never traded for anything
        return 1e6 * weight
    return weight


@numba.njit(cache=True)
def _set_cost(S, ns, stamp, tick, g, f, half, want, weight, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary):
    """Type mismatches over S[:ns] and their neighbours (each vertex once; a
    wrong extremum weighs 1e6 times a wrong saddle multiplicity) plus the
    distances of S[:ns] beyond the box f +- half."""
    c = 0.0
    for i in range(ns):
        v = S[i]
        for j in range(adj_ptr[v], adj_ptr[v + 1] + 1):
            w = v if j == adj_ptr[v + 1] else adj_nbr[j]
            if stamp[w] != tick:
                stamp[w] = tick
                c += _mismatch(w, g, want, weight, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary)
        e = abs(g[v] - f[v]) - half
        if e > 0.0:
            c += e
    return c


@numba.njit(cache=True)
def _gaps(v, g, f, half, reach, adj_ptr, adj_nbr, out):
    """Candidate values of v: in each open gap between its neighbours' values,
    the point closest to f(v) within f(v) +- max(half, reach); returns the count."""
    d = adj_ptr[v + 1] - adj_ptr[v]
    nv = np.empty(d, np.float64)
    for j in range(d):
        nv[j] = g[adj_nbr[adj_ptr[v] + j]]
    nv.sort()
    r = max(half, reach)
    k = 0
    for i in range(d + 1):
        lo = -np.inf if i == 0 else np.nextafter(nv[i - 1], np.inf)
        hi = np.inf if i == d else np.nextafter(nv[i], -np.inf)
        lo = max(lo, f[v] - r)
        hi = min(hi, f[v] + r)
        if lo > hi:
            continue
        out[k] = min(max(f[v], lo), hi)
        k += 1
    return k


@numba.njit(cache=True, inline="always")
def _enqueue_closed_ring(v, adj_ptr, adj_nbr, inq, queue, head, size):
    """Append ``v`` and its neighbours that are not queued yet to the ring buffer
    ``queue`` (capacity n, ``size`` entries from ``head``); returns the new size."""
    n = queue.shape[0]
    for j in range(adj_ptr[v], adj_ptr[v + 1] + 1):
        w = v if j == adj_ptr[v + 1] else adj_nbr[j]
        if not inq[w]:
            inq[w] = True
            queue[(head + size) % n] = w
            size += 1
    return size


@numba.njit(cache=True)
def refine_types(g, f, half, want, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary, max_moves):
    """Local search on g (in place): single-vertex moves that lower

        weight * #{vertices whose type differs from ``want``}
            + sum over vertices of max(0, |g - f| - half),

    with weight above any possible sum of the second term, so types come
    first. A move puts g(v) in one of the open gaps between its neighbours'
    values (one orientation of its link per gap), at the point of the gap
    closest to f(v), never further from f(v) than max(half, |g(v) - f(v)|);
    the best gap is taken if it strictly lowers the cost.
    Starts from the vertices that have a wrong type or leave the box and
    follows the neighbourhoods of the moves. Returns the number of moves.
    """
    n = g.shape[0]
    span = 0.0
    if n:
        span = (np.max(f) - np.min(f)) + (np.max(g) - np.min(g)) + 4.0 * half
    unit = span if span > 0.0 else 1.0  # the field's own scale: costs are compared in it, never in absolute units
    weight = 4.0 * unit * (n + 1)
    queue = np.empty(n, np.int64)
    inq = np.zeros(n, np.bool_)
    head = 0
    size = 0
    for v in range(n):
        bad = abs(g[v] - f[v]) > half
        if not bad:
            bad = vertex_type(v, g, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary) != want[v]
        if bad:
            queue[(head + size) % n] = v
            size += 1
            inq[v] = True
    moves = 0
    stamp = np.zeros(n, np.int64)
    tick = 0
    S = np.empty(2, np.int64)
    cv = np.empty(1, np.float64)
    cu = np.empty(1, np.float64)
    while size > 0 and moves < max_moves:
        v = queue[head]
        head = (head + 1) % n
        size -= 1
        inq[v] = False
        d = adj_ptr[v + 1] - adj_ptr[v]
        if d == 0:
            continue
        if cv.shape[0] < d + 1:
            cv = np.empty(2 * d + 2, np.float64)
        old = g[v]
        S[0] = v
        tick += 1
        best_c = _set_cost(S, 1, stamp, tick, g, f, half, want, weight, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary)
        best_x = old
        best_u = -1
        best_y = 0.0
        cv_best = old
        cu_best = old
        k = _gaps(v, g, f, half, abs(old - f[v]), adj_ptr, adj_nbr, cv)
        for i in range(k):
            x = cv[i]
            if x == old:
                continue
            g[v] = x
            tick += 1
            c = _set_cost(S, 1, stamp, tick, g, f, half, want, weight, adj_ptr, adj_nbr, vf_ptr, vf_tri, F,
                          boundary)
            if c < best_c - 1e-12 * (unit + abs(best_c)):
                best_c = c
                best_x = x
        g[v] = old
        wrong = vertex_type(v, g, adj_ptr, adj_nbr, vf_ptr, vf_tri, F, boundary) != want[v]
        if best_x == old and wrong:
            # no single move helps: try v together with one neighbour u
            for j in range(adj_ptr[v], adj_ptr[v + 1]):
                u = adj_nbr[j]
                S[1] = u
                old_u = g[u]
                tick += 1
                base = _set_cost(S, 2, stamp, tick, g, f, half, want, weight, adj_ptr, adj_nbr, vf_ptr, vf_tri, F,
                                 boundary)
                for i in range(k):
                    g[v] = cv[i]
                    du = adj_ptr[u + 1] - adj_ptr[u]
                    if cu.shape[0] < du + 1:
                        cu = np.empty(2 * du + 2, np.float64)
                    ku = _gaps(u, g, f, half, abs(old_u - f[u]), adj_ptr, adj_nbr, cu)
                    for i2 in range(ku):
                        g[u] = cu[i2]
                        tick += 1
                        c = _set_cost(S, 2, stamp, tick, g, f, half, want, weight, adj_ptr, adj_nbr, vf_ptr,
                                      vf_tri, F, boundary)
                        if c < base - 1e-12 * (unit + abs(base)) and (best_u == -1 or c - base < best_y):
                            best_u = u
                            best_y = c - base
                            cv_best = cv[i]
                            cu_best = cu[i2]
                    g[u] = old_u
                g[v] = old
            if best_u >= 0:
                g[v] = cv_best
                g[best_u] = cu_best
                moves += 1
                size = _enqueue_closed_ring(v, adj_ptr, adj_nbr, inq, queue, head, size)
                size = _enqueue_closed_ring(best_u, adj_ptr, adj_nbr, inq, queue, head, size)
            continue
        g[v] = best_x
        if best_x != old:
            moves += 1
            size = _enqueue_closed_ring(v, adj_ptr, adj_nbr, inq, queue, head, size)
    return moves
