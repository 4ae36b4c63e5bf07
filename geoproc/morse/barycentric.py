"""Optimal simplification on the barycentric subdivision: the bound P/2 exactly.

Bauer, Lange and Wardetzky's bound ``||f - g||_inf <= P/2`` holds for
Forman's discrete Morse functions, where every cell (vertex, edge, triangle)
carries its own value. A function on the vertices of the mesh alone cannot
always reach it (:mod:`geoproc.morse.simplify`, step 4). On the barycentric
subdivision every cell of the mesh becomes a vertex (its barycentre), so the
construction can be carried out cell by cell:

1. f on cells is the lower-star extension ``f(sigma) = max of f over the
   vertices of sigma`` (the filtration whose persistence the issue's gudhi
   reference computes; ties by the vertex order (value, index)).
2. The discrete gradient of f (ProcessLowerStars,
   :func:`geoproc.morse.gradient.discrete_gradient`) has one critical cell per
   persistence pair end and per essential class.
3. Every pair with persistence < P is cancelled by reversing the unique
   gradient path between its two critical cells (Forman's cancellation):
   minimum-saddle pairs along vertex-edge paths in increasing saddle order,
   saddle-maximum pairs along edge-triangle paths in decreasing saddle order
   (the elder rule guarantees the path, as in the persistence computation).
4. The cancelled gradient V' orders the cells: a face is below its cofacet
   unless the two are paired, then above. This relation is acyclic (V' is a
   gradient); a backward pass gives every cell the highest value its
   successors allow within f + P/2, a forward pass the value closest to f
   above its predecessors, both strictly (one unit in the last place).
   Cancelling a pair of persistence p < P needs a drop of p < P along its
   reversed path, so every value stays within f +- P/2 (the passes use a box
   narrower by 1e-9 P/2, so that breaking ties afterwards stays inside).
5. g on the subdivision's vertices (the cells' barycentres) is piecewise
   linear, and its critical vertices are exactly the barycentres of the
   critical cells of V': a kept minimum vertex, a kept saddle edge's midpoint,
   a kept maximum triangle's centre. Ties are removed by sorting by
   (value, index), which keeps every strict relation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from geoproc.errors import InputError
from geoproc.mesh.topology import referenced_vertices
from geoproc.morse.complex import SurfaceComplex, surface_complex
from geoproc.morse.dag import topological_order, values_in_box
from geoproc.morse.gradient import DiscreteGradient, discrete_gradient
from geoproc.morse.order import vertex_order
from geoproc.morse.persistence import PersistencePairs, lower_star_persistence
from geoproc.morse.simplify import _make_strict, strictly_increasing


@dataclass
class BarycentricSimplification:
    """g on the barycentric subdivision of the mesh.

    Attributes
    ----------
    V : (n + k + m, 3) float64
        Subdivision vertices: the n mesh vertices (input order), then the
        midpoints of the k edges ``E``, then the centroids of the m triangles.
    F : (6 m, 3) int64
        Subdivision triangles, oriented as the input's (six per triangle, in
        the input's triangle order).
    E : (k, 2) int64
        The mesh edges (input vertex ids, ``E[:, 0] < E[:, 1]``).
    dim : (n + k + m,) int8
        Dimension of the cell each subdivision vertex stands for.
    f : (n + k + m,) float64
        Lower-star extension of the input: each cell's largest vertex value.
    g : (n + k + m,) float64
        The simplified function, no ties.
    threshold : float
        P.
    critical : (c,) int64
        Subdivision vertices that are critical cells of the cancelled
        gradient (kept minima, saddles, maxima, essential classes).
    pairs_removed, pairs_kept : int
        Finite persistence pairs with persistence < P (cancelled) and >= P.
    max_abs_change : float
        ``max |f - g|`` over all cells.
    tie_slack : (cells,) float array or 0.0
        The rise that breaking g's ties gave each value
        (:func:`geoproc.morse.simplify.strictly_increasing`), in the order of ``g``.
    order, cx, gradient, pairs
        As in :class:`geoproc.morse.MorseSimplification`: the vertex order,
        and the complex, gradient and persistence pairs of f on the
        relabelled mesh (``order[i]`` is the input vertex of relabelled i).
    """

    V: np.ndarray
    F: np.ndarray
    E: np.ndarray
    dim: np.ndarray
    f: np.ndarray
    g: np.ndarray
    threshold: float
    critical: np.ndarray
    pairs_removed: int
    pairs_kept: int
    max_abs_change: float
    order: np.ndarray
    cx: SurfaceComplex
    gradient: DiscreteGradient
    pairs: PersistencePairs
    tie_slack: np.ndarray | float = 0.0


@numba.njit(cache=True)
def _across(X, e, c):
    """The cell on the other side of edge e from cell c (``X``: the edge's two
    vertices, or its two triangles); -1 across a boundary edge."""
    if X[e, 1] < 0:
        return -1
    return X[e, 0] + X[e, 1] - c


@numba.njit(cache=True)
def _root(X, cell_edge, c):
    """Follow cell -> paired edge -> cell across it up to an unpaired cell (or -1)."""
    while cell_edge[c] >= 0:
        c = _across(X, cell_edge[c], c)
        if c < 0:
            return -1
    return c


@numba.njit(cache=True)
def _cancel_pairs(X, cell_edge, edge_cell, saddles, ends):
    """Reverse the gradient path from each saddle edge to its partner cell.

    Minimum side: ``X`` = the edges' vertices, ``cell_edge`` / ``edge_cell``
    the vertex-edge pairs, ``ends`` the minima. Maximum side: ``X`` = the
    edges' triangles (-1 on the boundary), the triangle-edge pairs, the maxima.
    Pairs are tried in the given order; one whose partner is not yet the root
    behind either side of its edge is retried after the others. Returns the
    number of pairs that could not be cancelled.
    """
    todo = np.ones(len(saddles), dtype=np.bool_)
    left = len(saddles)
    while left:
        progress = False
        for i in range(len(saddles)):
            if not todo[i]:
                continue
            s = saddles[i]
            start = -1
            for side in range(2):
                c0 = X[s, side]
                if c0 >= 0 and _root(X, cell_edge, c0) == ends[i]:
                    start = c0
                    break
            if start < 0:
                continue
            c = start
            prev = s
            while True:
                e = cell_edge[c]
                cell_edge[c] = prev
                edge_cell[prev] = c
                if e < 0:
                    break
                prev = e
                c = _across(X, e, c)
            todo[i] = False
            left -= 1
            progress = True
        if not progress:
            return left
    return 0


@numba.njit(cache=True)
def _cell_arcs(E, FE, v_e, e_t, n):
    """Arcs (lower cell, upper cell) of the order V' puts on the cells (ids:
    vertices, then n + edge, then n + k + triangle)."""
    k = E.shape[0]
    m = FE.shape[0]
    lo = np.empty(2 * k + 3 * m, np.int64)
    hi = np.empty(2 * k + 3 * m, np.int64)
    a = 0
    for e in range(k):
        for j in range(2):
            x = E[e, j]
            if v_e[x] == e:
                lo[a], hi[a] = n + e, x
            else:
                lo[a], hi[a] = x, n + e
            a += 1
    for t in range(m):
        for j in range(3):
            e = FE[t, j]
            if e_t[e] == t:
                lo[a], hi[a] = n + k + t, n + e
            else:
                lo[a], hi[a] = n + e, n + k + t
            a += 1
    return lo, hi


def _strict_along_arcs(fc, lo, hi):
    """fc with its ties broken along the arcs ``lo -> hi`` (a cell below its
    cofacet unless the gradient pairs them): tied values rise by units in the
    last place in a topological order, so that the critical points of the
    result are the gradient's critical cells. A face and its cofacet always
    tie in the lower-star extension (a cell has its highest vertex's value);
    breaking those ties by index put every vertex below its whole star, and a
    constant field had every cell critical."""
    N = fc.shape[0]
    _, _, topo, count, _ = topological_order(lo, hi, N)
    if count < N:
        raise RuntimeError("the gradient has a closed path")
    rank = np.empty(N, np.int64)
    rank[topo] = np.arange(N)
    return _make_strict(fc, np.lexsort((rank, fc)))


@numba.njit(cache=True)
def _assign_cell_values(lo, hi, fc, delta):
    """Values in [fc - delta, fc + delta] strictly increasing along every arc,
    as close to fc as the arcs allow. Returns (g, ok); ok is False when the
    arcs have a cycle."""
    N = fc.shape[0]
    ptr, succ, topo, count, _ = topological_order(lo, hi, N)
    if count < N:
        return np.empty(N), False
    return values_in_box(fc, np.full(N, delta), ptr, succ, topo), True


def mesh_cell(result: BarycentricSimplification, F: np.ndarray, vertex: int) -> dict:
    """The mesh cell a subdivision vertex stands for.

    Parameters
    ----------
    result : the output of :func:`barycentric_simplify`; F : (m, 3) the input triangles;
    vertex : a subdivision vertex id.

    Returns
    -------
    dict with ``dimension`` (0, 1, 2) and ``vertices`` (the cell's input vertex ids).
    """
    n, k = len(result.V) - len(result.E) - len(F), len(result.E)
    if vertex < n:
        return {"dimension": 0, "vertices": [int(vertex)]}
    if vertex < n + k:
        return {"dimension": 1, "vertices": [int(x) for x in result.E[vertex - n]]}
    return {"dimension": 2, "vertices": [int(x) for x in F[vertex - n - k]]}


def subdivision_values(result: BarycentricSimplification, F: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per-vertex values of the mesh carried to the subdivision vertices:
    kept at mesh vertices, averaged over the edge's and the triangle's
    vertices at midpoints and centroids (linear interpolation).

    Parameters
    ----------
    result : the output of :func:`barycentric_simplify`; F : (m, 3) the input triangles;
    values : (n,) or (n, c) numeric array per input vertex.

    Returns
    -------
    (n + k + m,) or (n + k + m, c), in the type of ``values``: integer averages
    are rounded to the nearest integer (uchar colours stay colours), float32
    stays float32, anything else is float64.
    """
    a = np.asarray(values)
    wide = a.astype(np.float64)
    mixed = np.concatenate([wide, wide[result.E].mean(axis=1), wide[F].mean(axis=1)])
    if a.dtype.kind in "iu":  # a mean of values in the type's range stays in it
        return np.rint(mixed).astype(a.dtype)
    return mixed.astype(np.float32) if a.dtype == np.float32 else mixed


def barycentric_subdivision(V: np.ndarray, F: np.ndarray, E: np.ndarray, FE: np.ndarray) -> tuple[np.ndarray,
                                                                                                   np.ndarray]:
    """Vertices and triangles of the barycentric subdivision.

    Parameters
    ----------
    V : (n, 3) positions; F : (m, 3) triangles; E : (k, 2) edges;
    FE : (m, 3) edge of ``F[t, j] -> F[t, (j + 1) % 3]``.

    Returns
    -------
    V_sd : (n + k + m, 3) vertices, edge midpoints, triangle centroids;
    F_sd : (6 m, 3) triangles ``(corner, edge midpoint, centre)`` and
    ``(edge midpoint, next corner, centre)`` for each edge of each triangle,
    oriented as the triangle.
    """
    n, k, m = len(V), len(E), len(F)
    V_sd = np.empty((n + k + m, 3))
    V_sd[:n] = V
    np.add(V[E[:, 0]], V[E[:, 1]], out=V_sd[n:n + k])
    V_sd[n:n + k] *= 0.5
    V_sd[n + k:] = V[F].mean(axis=1)
    F_sd = np.empty((m, 6, 3), dtype=np.int64)
    F_sd[:, :, 2] = (n + k + np.arange(m))[:, None]
    for j in range(3):
        F_sd[:, 2 * j, 0] = F[:, j]
        F_sd[:, 2 * j, 1] = F_sd[:, 2 * j + 1, 0] = n + FE[:, j]
        F_sd[:, 2 * j + 1, 1] = F[:, (j + 1) % 3]
    return V_sd, F_sd.reshape(-1, 3)


def barycentric_simplify(V: np.ndarray, F: np.ndarray, f: np.ndarray, threshold: float,
                         path: str | None = None) -> BarycentricSimplification:
    """Remove every persistence pair of f with persistence < threshold, with
    ``||f - g||_inf <= threshold / 2`` on the barycentric subdivision.

    Parameters
    ----------
    V : (n, 3) float array
        Vertex positions (only used for the subdivision's positions).
    F : (m, 3) int array
        Triangles of a 2-manifold mesh (boundary and several components allowed).
    f : (n,) float array
        Vertex values.
    threshold : float
        Absolute persistence threshold P >= 0. With P = 0 nothing is removed
        and g is the lower-star extension itself, its ties (a cell and its
        highest vertex, and all of a constant field) broken by units in the
        last place along the gradient, so that g's critical points are the
        gradient's critical cells.
    path : str, optional
        File name for error messages.

    Returns
    -------
    BarycentricSimplification

    Raises
    ------
    InputError
        When some vertex no face uses: it is no cell of the surface (as
        :func:`geoproc.morse.morse_simplify` leaves it out), and the
        subdivision would carry it as an isolated point.
    RuntimeError
        If a cancellation path is missing or the cancelled gradient has a
        closed path (neither happens for a gradient built by
        ProcessLowerStars and pairs from the elder rule).
    """
    f = np.asarray(f, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = len(f)
    unused = ~referenced_vertices(F, n)
    if unused.any():  # (the command leaves them out first, as geoproc.mesh.clean.remove_unreferenced_vertices does)
        raise InputError(path, f"{int(unused.sum())} vertices no face uses (first: {int(np.flatnonzero(unused)[0])}):"
                               " they are no cells of the surface; remove them before the subdivision")
    P = float(threshold)
    order, rank = vertex_order(f)
    cx = surface_complex(rank[F], n, path)
    fr = f[order]
    grad = discrete_gradient(cx, fr)
    pp = lower_star_persistence(cx, fr)
    p0 = fr[pp.edge_top[pp.min_saddle_edge]] - fr[pp.min_vertex]
    p1 = fr[pp.triangle_top[pp.max_triangle]] - fr[pp.edge_top[pp.saddle_edge]]
    v_e, e_v = grad.vertex_edge.copy(), grad.edge_vertex.copy()
    e_t, t_e = grad.edge_triangle.copy(), grad.triangle_edge.copy()
    cut0 = np.flatnonzero(p0 < P)
    cut0 = cut0[np.lexsort((pp.min_saddle_edge[cut0], pp.edge_top[pp.min_saddle_edge[cut0]]))]
    left = _cancel_pairs(cx.E, v_e, e_v, pp.min_saddle_edge[cut0], pp.min_vertex[cut0])
    cut1 = np.flatnonzero(p1 < P)
    cut1 = cut1[np.lexsort((pp.saddle_edge[cut1], pp.edge_top[pp.saddle_edge[cut1]]))][::-1]
    left += _cancel_pairs(cx.ET, t_e, e_t, pp.saddle_edge[cut1], pp.max_triangle[cut1])
    if left:
        raise RuntimeError(f"{left} persistence pairs have no gradient path to cancel along")
    k, m = len(cx.E), len(cx.F)
    fc = np.concatenate([fr, fr[pp.edge_top], fr[pp.triangle_top]])
    lo, hi = _cell_arcs(cx.E, cx.FE, v_e, e_t, n)
    # The box is narrowed by a margin far below any value difference so that
    # the tie-breaking below (one unit in the last place per tied cell) cannot
    # leave it; a cancelled pair whose persistence is within that margin of P
    # gets the full box.
    margin = max(1e-9 * P / 2.0, 1024 * np.spacing(float(np.abs(fc).max())) if len(fc) else 0.0)
    if P == 0.0:  # nothing to remove: g is f on the cells, ties broken along the gradient
        g = _strict_along_arcs(fc, lo, hi)
    for half in (P / 2.0 - margin, P / 2.0) if P / 2.0 > margin else ((P / 2.0,) if P > 0.0 else ()):
        g, ok = _assign_cell_values(lo, hi, fc, half)
        if not ok:
            raise RuntimeError("the cancelled gradient has a closed path")
        if (g >= fc - half).all():
            break
    slack = 0.0
    if P > 0.0:
        g, slack = strictly_increasing(g)
    critical = np.concatenate([np.flatnonzero(v_e < 0), n + np.flatnonzero((e_v < 0) & (e_t < 0)),
                               n + k + np.flatnonzero(t_e < 0)])
    # back to the input's vertex numbering (edges and triangles keep theirs)
    E_in = np.sort(order[cx.E], axis=1)
    V_sd, F_sd = barycentric_subdivision(np.asarray(V, dtype=np.float64), F, E_in, cx.FE)
    to_input = np.concatenate([order, np.arange(n, n + k + m)])
    f_out = np.empty_like(fc)
    g_out = np.empty_like(g)
    f_out[to_input] = fc
    g_out[to_input] = g
    if np.ndim(slack):
        slack_out = np.empty_like(slack)
        slack_out[to_input] = slack
        slack = slack_out
    dim = np.concatenate([np.zeros(n), np.ones(k), np.full(m, 2)]).astype(np.int8)
    return BarycentricSimplification(
        V=V_sd, F=F_sd, E=E_in, dim=dim, f=f_out, g=g_out, threshold=P,
        critical=np.sort(to_input[critical]), pairs_removed=int(len(cut0) + len(cut1)),
        pairs_kept=int(len(p0) + len(p1) - len(cut0) - len(cut1)),
        max_abs_change=float(np.max(np.abs(g - fc))) if len(g) else 0.0,
        order=order, cx=cx, gradient=grad, pairs=pp, tie_slack=slack,
    )
