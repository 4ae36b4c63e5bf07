"""Optimal topological simplification of a function on a surface
(Bauer, Lange, Wardetzky, "Optimal topological simplification of discrete
functions on surfaces", Discrete Comput. Geom. 47, 2012).

Given f and a threshold P > 0, build g with ||f - g||_inf <= P/2 whose critical
points are those of f in persistence pairs with persistence >= P (and the
essential ones), and no others. P/2 is optimal: by the stability theorem no
function closer to f can lose a pair of persistence P.

How g is built
--------------
1. Which pairs go. Union-find over the vertices in the total order (value,
   index) grows the sublevel-set components with a descent forest (each vertex
   points to its lowest neighbour). When a component dies at a saddle with
   persistence < P, its descent path from the merging edge down to its minimum
   is reversed and continued across the edge (Forman's cancellation): the
   whole basin now drains into the older component. The same on -f over the
   mesh with its boundary coned off by a virtual vertex above everything (a
   region that reaches the boundary is no peak) picks the maxima that stay.
2. Basins flooded. The descent forest, plus "every neighbour is above" for each
   minimum that stays, is an acyclic relation a < b. Values are assigned in
   the box [f - P/2, f + P/2]: a backward pass gives each vertex the largest
   value hi(v) <= f(v) + P/2 from which all its successors can still be
   reached strictly increasing (saddles carved down), a forward pass sets
   g(v) = max(min(f(v), hi(v)), next float above g of every predecessor)
   (basins flooded up), so g = f wherever no cancellation reaches, and
   f - P/2 <= g <= f + P/2 (every descent chain drops by less than P).
3. Peaks carved. The ascent forest is rebuilt on the flooded function (so
   ascents agree with the flooding), peaks that go have their ascent path
   reversed across their saddle, and both forests plus "every neighbour is
   below" for each maximum that stays are assigned in one pass as in 2.
   Saddle vertices none of whose pairs is cancelled also keep every edge of
   their link oriented as in f, so they stay saddles of the same multiplicity
   at the same vertex; a held saddle whose link takes part in a cycle of the
   relation or needs a wider box is let go (the bound comes first).
4. Where P/2 cannot be met. For piecewise-linear vertex functions the bound
   P/2 (optimal for Forman's discrete Morse functions, where every cell has
   its own value) is not always reachable. Every g with exactly the kept
   extrema gives each other vertex a lower neighbour and (interior vertices)
   an upper one; where a cancelled minimum m and a cancelled maximum M can
   only escape across the same vertex s, g(M) < g(s) < g(m) follows and
   some vertex moves by more than P/2 (tests/geoproc/test_morse_bound.py
   certifies such windows with interval propagation and an exact
   mixed-integer program: bunny and armadillo with 2% noise at P = 1% of the
   range). On the barycentric subdivision, where every cell has its own
   vertex, the bound always holds (:mod:`geoproc.morse.barycentric`). Chains
   the relation cannot fit in the box get the smallest local
   widening that makes them feasible (half the drop of the chain through the
   vertex); this is not always the least possible, step 7 below takes the
   worst places closer; a vertex where the ascent and descent witnesses
   disagree (a cycle of the relation) loses its ascent witness.
5. Exact critical points. Monotone sweeps (Tierny and Pascucci 2012) from the
   minima that stay (raising) and from the maxima that stay and the boundary
   (lowering) are repeated until every vertex has the wanted status; they are
   skipped when steps 2-3 already produced the right extrema. After a repair
   (or a widening) the values are refitted: the steepest descent and ascent
   neighbours of the current g become the witnesses (consistent with g, so
   the relation is acyclic and the extrema stay right) and step 2's passes
   assign values again as close to f as they allow, kept while this lowers
   max |f - g|. The vertices where |f - g| > P/2 are reported.
6. Exact critical vertices. Every vertex gets a wanted type: minimum (kept
   minima), maximum (kept maxima), a saddle of multiplicity m(v) - c(v)
   (m: f's critical edges with highest vertex v, c: cancelled pairs dying at
   v), else regular. A local search (:func:`geoproc.morse.refine.refine_types`)
   moves the value of one vertex, or of a vertex and a neighbour, into another
   gap between its neighbours' values (never further from f than P/2 or than
   it already is) while this lowers the number of vertices of the wrong type
   (a wrong extremum is never traded) and then the total distance beyond
   f +- P/2. On the noisy height fields of the tests this puts every kept
   saddle back at its own vertex (armadillo with 2% noise: 10 of 7,496 kept
   saddle edges stay at a neighbouring vertex at P = 1% of the range, 8 of
   115 at 5%).
7. Exact windows. Around the vertices still beyond f +- P/2 (or of the
   wrong type) a window (the vertex and its neighbours; touching windows
   merged) is re-solved exactly (:mod:`geoproc.morse.window_repair`): a small
   mixed-integer program (scipy's HiGHS) over the window's values, with one
   orientation bit per edge and the type of every vertex in and around the
   window fixed (the lower-link count of :mod:`geoproc.morse.refine`,
   linearised), values outside held, minimises max |f - g| over the window;
   the order it picks is turned into values as close to f as it allows and
   written back when every type checks out and the window gets closer to f.
   The windows farthest from f go first, four by default
   (``exact_windows``; -1: all, then the 8 farthest again with wider
   windows, the 2- and 4-rings). The hand-made monkey saddle of the tests
   reaches its exact bound 0.55 P this way; on the noisy height fields of the
   tests with 2% noise: fertility at P = 2% of the range 0.766 P -> 0.561 P
   (certified least for these vertex types by test_morse_bound), camelhead
   at 5% 0.571 P -> 0.557 P, armadillo at 1% 0.903 P -> 0.868 P and at 5%
   0.767 P -> 0.713 P; with all windows spot at 5% gets to P/2 (0.523 P
   before), camelhead to one vertex beyond P/2 (nine before); bunny at 1%
   stays at its certified bound 0.802 P.
8. Made strict: vertices are sorted by (g, index) and equal values are moved
   up by one unit in the last place, so g has no ties (the (value, index)
   order, and so every vertex type, is unchanged); sorting its vertices by
   (value, index) gives exactly the kept minima and maxima and, by
   c0 - c1 + c2 = chi, exactly as many saddles (with multiplicity) as the kept
   pairs and essential classes need.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from geoproc.morse.complex import SurfaceComplex
from geoproc.morse.dag import topological_order, values_in_box
from geoproc.morse.gradient import DiscreteGradient, discrete_gradient
from geoproc.morse.heap import heap_pop, heap_push
from geoproc.morse.merge_forest import cone_adjacency, merge_forest
from geoproc.morse.order import vertex_order
from geoproc.morse.refine import refine_types, vertex_faces
from geoproc.morse.window_repair import BOX_WIDENING, half_bound_tolerance, repair_windows


@dataclass
class Simplification:
    """The simplified function and what was cancelled.

    Attributes
    ----------
    g : (n,) float64 array
        The simplified function, without ties.
    threshold : float
        Absolute persistence threshold P.
    kept_minima, kept_maxima : int64 arrays
        Vertices that stay minima / maxima (sorted).
    pairs_removed, pairs_kept : int
        Finite persistence pairs (both dimensions, zero persistence included)
        with persistence < P and >= P.
    max_abs_change : float
        ``max |f - g|``.
    widened_vertices : int64 array
        Vertices with |f - g| > P/2 past rounding (:func:`geoproc.morse.window_repair.half_bound_tolerance`
        with ``tie_slack``; see step 4 of the module docstring).
    repaired_vertices : int
        Value changes made by the repair sweeps of step 5 (0 when the
        cancellation relation alone gave the right extrema).
    tie_slack : (n,) float array or 0.0
        The rise that breaking ties gave each value (step 8, and before
        the windows of step 7): one unit in the last place per tied vertex, so
        a plateau of k vertices at f + P/2 ends up to k units beyond it. Moves
        past P/2 within it, up to :data:`~geoproc.morse.window_repair.TIE_ROUNDING`
        of P/2, are tie-breaking, not counted in ``widened_vertices``.
    """

    g: np.ndarray
    threshold: float
    kept_minima: np.ndarray
    kept_maxima: np.ndarray
    pairs_removed: int
    pairs_kept: int
    max_abs_change: float
    widened_vertices: np.ndarray
    repaired_vertices: int
    tie_slack: np.ndarray | float = 0.0


@numba.njit(cache=True)
def _assign_values(f, half, down, up, keep_min, keep_max, pin, adj_ptr, adj_nbr):
    """Backward and forward passes of step 3; returns (g, half-width used per
    vertex, stuck) where ``stuck`` marks vertices on a cycle of the relation
    (none when it is acyclic)."""
    n = f.shape[0]
    # relation a < b as edge lists
    cnt = 0
    for v in range(n):
        if down[v] >= 0:
            cnt += 1
        if up[v] >= 0 and up[v] < n:
            cnt += 1
        if keep_min[v] or keep_max[v] or pin[v]:
            cnt += adj_ptr[v + 1] - adj_ptr[v]
    A = np.empty(cnt, np.int64)
    B = np.empty(cnt, np.int64)
    c = 0
    for v in range(n):
        if down[v] >= 0:
            A[c] = down[v]
            B[c] = v
            c += 1
        if up[v] >= 0 and up[v] < n:
            A[c] = v
            B[c] = up[v]
            c += 1
        if keep_min[v]:
            for j in range(adj_ptr[v], adj_ptr[v + 1]):
                A[c] = v
                B[c] = adj_nbr[j]
                c += 1
        if keep_max[v]:
            for j in range(adj_ptr[v], adj_ptr[v + 1]):
                A[c] = adj_nbr[j]
                B[c] = v
                c += 1
        elif pin[v] and not keep_min[v]:  # a kept saddle keeps its link as in f
            for j in range(adj_ptr[v], adj_ptr[v + 1]):
                w = adj_nbr[j]
                if f[w] < f[v] or (f[w] == f[v] and w < v):
                    A[c] = w
                    B[c] = v
                else:
                    A[c] = v
                    B[c] = w
                c += 1
    ptr, succ, topo, tail, indeg = topological_order(A[:c], B[:c], n)
    g = np.empty(n, np.float64)
    half_v = np.full(n, half)
    stuck = indeg > 0
    if tail < n:
        return g, half_v, stuck
    # widest drop of f along any chain through each vertex
    top = f.copy()  # max of f over the vertex and everything before it
    for i in range(n):
        a = topo[i]
        for j in range(ptr[a], ptr[a + 1]):
            b = succ[j]
            if top[a] > top[b]:
                top[b] = top[a]
    bot = f.copy()  # min of f over the vertex and everything after it
    for i in range(n - 1, -1, -1):
        a = topo[i]
        for j in range(ptr[a], ptr[a + 1]):
            b = succ[j]
            if bot[b] < bot[a]:
                bot[a] = bot[b]
    for v in range(n):
        d = max(top[v] - f[v], f[v] - bot[v])
        if d >= 2.0 * half:
            half_v[v] = 0.5 * d * (1.0 + BOX_WIDENING) + 1e-300
    return values_in_box(f, half_v, ptr, succ, topo), half_v, stuck


@numba.njit(cache=True)
def _flood_from(g, seeds, adj_ptr, adj_nbr, sign):
    """Monotone sweep from ``seeds`` on sign * g (Tierny and Pascucci 2012):
    vertices are taken in increasing sign * g among those next to the swept
    region, and each gets at least the next float above the previous one, so
    every vertex but the seeds has a neighbour swept before it, strictly below
    it. Raises (sign = 1) or lowers (sign = -1) values only. Returns the
    number of changed vertices."""
    n = g.shape[0]
    h = sign * g
    seen = np.zeros(n, np.bool_)
    keys = np.empty(adj_nbr.shape[0] + n + 1, np.float64)
    items = np.empty(adj_nbr.shape[0] + n + 1, np.int64)
    size = 0
    for v in range(n):
        if seeds[v]:
            seen[v] = True
            size = heap_push(keys, items, size, h[v], v)
    changed = 0
    last = -np.inf
    while size > 0:
        v, size = heap_pop(keys, items, size)
        if h[v] <= last:
            h[v] = np.nextafter(last, np.inf)
            changed += 1
        last = h[v]
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            w = adj_nbr[j]
            if not seen[w]:
                seen[w] = True
                size = heap_push(keys, items, size, h[w], w)
    for v in range(n):
        g[v] = sign * h[v]
    return changed


@numba.njit(cache=True)
def _wrong_extrema(g, keep_min, keep_max, boundary, adj_ptr, adj_nbr):
    """Number of vertices whose min/max status under (g, index) differs from
    the wanted one (maxima: interior vertices only)."""
    n = g.shape[0]
    bad = 0
    for v in range(n):
        lower = False
        higher = False
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            w = adj_nbr[j]
            if g[w] < g[v] or (g[w] == g[v] and w < v):
                lower = True
            else:
                higher = True
        if lower == keep_min[v]:
            bad += 1
        if adj_ptr[v + 1] > adj_ptr[v] and not boundary[v] and higher == keep_max[v]:
            bad += 1
    return bad


def strictly_increasing(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """g (n,) with its ties broken upwards in (value, index) order (step 8), and
    the rise that gave each value (n,), 0 without ties. A plateau of k values
    rises by up to k units in the last place; where the field's range holds
    fewer doubles than there are values, the rises run on past the range."""
    out = _make_strict(g, np.lexsort((np.arange(len(g)), g)))
    return out, out - g


@numba.njit(cache=True)
def _make_strict(g, order):
    out = g.copy()
    for i in range(1, order.shape[0]):
        a = out[order[i - 1]]
        if out[order[i]] <= a:
            out[order[i]] = np.nextafter(a, np.inf)
    return out


@numba.njit(cache=True)
def _lowest_neighbour(g, adj_ptr, adj_nbr, keep_min, fallback):
    """Each vertex's lowest neighbour under (g, index) when it is below the
    vertex, else ``fallback``; -1 for the minima that stay."""
    n = g.shape[0]
    out = np.full(n, -1, np.int64)
    for v in range(n):
        if keep_min[v]:
            continue
        best = -1
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            w = adj_nbr[j]
            if best == -1 or g[w] < g[best] or (g[w] == g[best] and w < best):
                best = w
        if best >= 0 and (g[best] < g[v] or (g[best] == g[v] and best < v)):
            out[v] = best
        else:
            out[v] = fallback[v]
    return out


def _saddle_multiplicity(cx: SurfaceComplex, f: np.ndarray, grad: DiscreteGradient | None) -> np.ndarray:
    """Number of critical edges of f's gradient whose highest vertex is v."""
    if grad is None:
        grad = discrete_gradient(cx, f)
    E = cx.E[grad.critical_edges]
    _, rank = vertex_order(f)
    top = np.where(rank[E[:, 0]] > rank[E[:, 1]], E[:, 0], E[:, 1])
    return np.bincount(top, minlength=len(f)).astype(np.int64)


@numba.njit(cache=True)
def _highest_neighbour(g, adj_ptr, adj_nbr):
    """Each vertex's highest neighbour under (g, index) when above it, else -1."""
    n = g.shape[0]
    out = np.full(n, -1, np.int64)
    for v in range(n):
        best = -1
        for j in range(adj_ptr[v], adj_ptr[v + 1]):
            w = adj_nbr[j]
            if best == -1 or g[w] > g[best] or (g[w] == g[best] and w > best):
                best = w
        if best >= 0 and (g[best] > g[v] or (g[best] == g[v] and best > v)):
            out[v] = best
    return out


def _ascent_forest(ptr, nbr, eid, f, threshold, keep):
    """merge_forest on -f over the coned adjacency (cone vertex = index n, above all)."""
    n = len(f)
    order, _ = vertex_order(f)
    order_up = np.concatenate([[n], order[::-1]]).astype(np.int64)
    rank_up = np.empty(n + 1, np.int64)
    rank_up[order_up] = np.arange(n + 1)
    value_up = np.concatenate([-f, [-np.inf]])
    b, d, _, _, up, _, _ = merge_forest(ptr, nbr, eid, order_up, rank_up, value_up, threshold, True, keep)
    return b, d, up


def _cancel(cx, f, P, down, up, keep_min, keep_max, seeds_max, pin):
    """Steps 3-5 for given witnesses; returns (g, widened mask, repaired count)."""
    up = up.copy()
    pin = pin.copy()
    for _ in range(4):
        for _ in range(16):
            g, half_v, stuck = _assign_values(f, P / 2.0, down, up, keep_min, keep_max, pin,
                                              cx.adj_ptr, cx.adj_nbr)
            if not stuck.any():
                break
            around = stuck.copy()
            around[cx.E[:, 0]] |= stuck[cx.E[:, 1]]
            around[cx.E[:, 1]] |= stuck[cx.E[:, 0]]
            if (pin & around).any():  # first let go of held saddles near the cycle
                pin &= ~around
                continue
            up[stuck] = -1  # conflicting ascent witnesses: left to the sweeps below
        else:
            raise RuntimeError("cancellation relation keeps a cycle")
        # a pinned saddle whose link needs a wider box is let go
        wide = half_v > P / 2.0
        near = wide.copy()
        near[cx.E[:, 0]] |= wide[cx.E[:, 1]]
        near[cx.E[:, 1]] |= wide[cx.E[:, 0]]
        loosen = pin & near
        if not loosen.any():
            break
        pin &= ~loosen
    # Repair (Tierny-Pascucci sweeps): only acts where the relation above
    # could not be kept; normally changes nothing.
    repaired = 0
    for _ in range(50):
        if _wrong_extrema(g, keep_min, keep_max, cx.boundary, cx.adj_ptr, cx.adj_nbr) == 0:
            break
        repaired += _flood_from(g, keep_min, cx.adj_ptr, cx.adj_nbr, 1.0)
        repaired += _flood_from(g, seeds_max, cx.adj_ptr, cx.adj_nbr, -1.0)
    wide = half_v > P / 2.0
    for _ in range(3 if (repaired or wide.any()) else 0):
        # Refit: g has the right extrema; read its steepest descent and ascent
        # witnesses (consistent with g, so acyclic) and assign values again as
        # close to f as they allow; kept while it lowers max |f - g|.
        none = np.full(len(f), -1, np.int64)
        down_r = _lowest_neighbour(g, cx.adj_ptr, cx.adj_nbr, keep_min, none)
        up_r = _highest_neighbour(g, cx.adj_ptr, cx.adj_nbr)
        up_r[keep_max | cx.boundary] = -1
        g_r, half_r, stuck = _assign_values(f, P / 2.0, down_r, up_r, keep_min, keep_max,
                                            np.zeros(len(f), np.bool_), cx.adj_ptr, cx.adj_nbr)
        if (stuck.any() or np.abs(g_r - f).max() >= np.abs(g - f).max()
                or _wrong_extrema(g_r, keep_min, keep_max, cx.boundary, cx.adj_ptr, cx.adj_nbr)):
            break
        g, wide = g_r, half_r > P / 2.0
    return g, wide, repaired


def simplify_function(cx: SurfaceComplex, f: np.ndarray, threshold: float,
                      gradient: DiscreteGradient | None = None, exact_windows: int = 4) -> Simplification:
    """Remove every persistence pair of f with persistence < threshold.

    Parameters
    ----------
    cx : SurfaceComplex
        A 2-manifold mesh (boundary and several components allowed).
    f : (n,) float array
        Vertex values.
    threshold : float
        Absolute persistence threshold P >= 0 (in f's units). With P = 0
        nothing is removed and g = f (ties, if any, stay and are broken by
        vertex index).
    gradient : DiscreteGradient, optional
        f's gradient, when already computed (its critical edges locate the
        saddles to keep in place).
    exact_windows : int
        How many windows around the vertices still beyond f +- P/2 are
        re-solved exactly, the farthest from f first (step 7 of the module
        docstring; each costs a small mixed-integer program, about 10-40 ms);
        0 for none; -1 for all of them, and those of the wrong saddle type,
        then the 8 farthest from f again with the vertices' 2- and 4-rings
        (windows up to 120 vertices; seconds on the 3k-11k vertex meshes of
        the tests, 30 s on armadillo at P = 5% of the range).

    Returns
    -------
    Simplification
        g whose minima and maxima are exactly the kept ones, with
        ``|f - g| <= P/2`` (up to units in the last place) except at the
        vertices listed in ``widened_vertices``; see the module docstring.
    """
    f = np.asarray(f, dtype=np.float64)
    n = len(f)
    P = float(threshold)
    order, rank = vertex_order(f)
    no_keep = np.zeros(n + 1, dtype=bool)
    b0, d0, _, _, down, _, _ = merge_forest(cx.adj_ptr, cx.adj_nbr, cx.adj_edge, order, rank, f, P,
                                            True, no_keep)
    ptr, nbr, eid = cone_adjacency(cx.adj_ptr, cx.adj_nbr, cx.adj_edge, cx.boundary)
    b1, d1, up_f = _ascent_forest(ptr, nbr, eid, f, P, no_keep)
    pers = np.concatenate([f[d0] - f[b0], f[b1] - f[d1]])
    removed = int((pers < P).sum())
    degree = np.diff(cx.adj_ptr)
    keep_min = down == -1
    keep_max = (up_f[:n] == -1) & ~cx.boundary & (degree > 0)
    repaired = 0
    slack = 0.0
    if P == 0.0:
        g = f.copy()
    else:
        no = np.zeros(n, dtype=bool)
        none = np.full(n, -1, dtype=np.int64)
        cancelled = np.concatenate([d0[f[d0] - f[b0] < P], d1[f[b1] - f[d1] < P]])
        mult = _saddle_multiplicity(cx, f, gradient)
        pin = mult > 0
        pin[cancelled] = False
        want = mult - np.bincount(cancelled, minlength=n)
        want[keep_min] = -1
        want[keep_max] = -2
        # minima first: descent forest of f with cancelled basins flooded
        g_min, _, _ = _assign_values(f, P / 2.0, down, none, keep_min, no, no, cx.adj_ptr, cx.adj_nbr)
        # then the ascent witnesses are read on the flooded function, peaks carved
        keep_up = np.concatenate([keep_max, [False]])
        _, _, up = _ascent_forest(ptr, nbr, eid, g_min, np.inf, keep_up)
        seeds_max = keep_max | cx.boundary | (degree == 0)
        args = (cx, f, P, down, up[:n], keep_min, keep_max, seeds_max)
        g, _, repaired = _cancel(*args, pin)
        vf_ptr, vf_tri = vertex_faces(cx.F, n)
        refine_types(g, f, P / 2.0, want, cx.adj_ptr, cx.adj_nbr, vf_ptr, vf_tri, cx.F, cx.boundary, 100 * n)
        if exact_windows:
            g, slack = strictly_increasing(g)  # no ties: the windows' values fit between
            repair_windows(g, f, P, want, cx, vf_ptr, vf_tri, exact_windows, slack=slack)
            for radius in () if exact_windows >= 0 else (2, 4):  # all: the 8 farthest again, wider
                repair_windows(g, f, P, want, cx, vf_ptr, vf_tri, 8, radius, 120, 50, slack=slack)
        g, rise = strictly_increasing(g)
        slack = slack + rise
    return Simplification(
        g=g,
        threshold=P,
        kept_minima=np.flatnonzero(keep_min),
        kept_maxima=np.flatnonzero(keep_max),
        pairs_removed=removed,
        pairs_kept=int(len(pers) - removed),
        max_abs_change=float(np.max(np.abs(g - f))) if n else 0.0,
        widened_vertices=np.flatnonzero(np.abs(g - f) > half_bound_tolerance(f, P / 2.0, slack)),
        repaired_vertices=repaired,
        tie_slack=slack,
    )
