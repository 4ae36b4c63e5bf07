"""Exact repair of small windows: where a simplified function g leaves the box
f +- P/2 (or a vertex has the wrong type), solve for the values of a window of
vertices around it that minimise max |f - g| over the window with every vertex
type in and around the window fixed, the values outside held.

The type of a vertex depends only on which of its neighbours are below it
(see :mod:`geoproc.morse.refine`): with an orientation bit o(c, a) = [a below
c] per edge and, for each triangle (c, a, b), the product o(c, a) o(c, b),

- a minimum has every bit 0, an interior maximum every bit 1;
- a saddle of multiplicity k (k = 0: regular) has
  sum_a o(c, a) - sum_(c,a,b) o(c, a) o(c, b) = k + 1, and (interior) not
  every bit 1.

With the bits as binaries (products linearised), strict order as
g_c - g_a >= eps - M (1 - o(c, a)) and its converse (no margin for the
orientation g already has, so g itself is feasible; a bit the value
intervals cannot flip is a constant), and |g - f| <= t, this is a small
mixed-integer program (scipy's HiGHS). Its optimum is the least max |f - g|
over the window for any function with the same values outside and the same
types on the window and its neighbours, up to eps (1e-5 P). The order of the
solution (its bits) is then turned into values exactly, as close to f as that
order allows within the optimum, one unit in the last place apart where it is
tight; they are written back only when every vertex type checks out in
floating point and the window gets closer to f.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix

from geoproc.c_output import c_stdout_silenced
from geoproc.morse.refine import vertex_type, vertex_types


def _ball(seed: np.ndarray, adj_ptr, adj_nbr, radius: int) -> np.ndarray:
    S = np.asarray(seed, dtype=np.int64)
    for _ in range(radius):
        S = np.union1d(S, np.concatenate([adj_nbr[adj_ptr[v]:adj_ptr[v + 1]] for v in S]))
    return S


def _windows(bad: np.ndarray, adj_ptr, adj_nbr, radius: int) -> list[np.ndarray]:
    """Groups of bad vertices whose radius-``radius`` balls touch, as the union
    of those balls (one window each)."""
    idx = np.flatnonzero(bad)
    if len(idx) == 0:
        return []
    W = [_ball(np.array([v]), adj_ptr, adj_nbr, radius) for v in idx]
    parent = list(range(len(W)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner: dict[int, int] = {}
    for i, S in enumerate(W):
        # touching: within one edge of each other
        for v in _ball(S, adj_ptr, adj_nbr, 1).tolist():
            j = owner.setdefault(v, i)
            if j != i:
                a, b = find(i), find(j)
                if a != b:
                    parent[a] = b
    groups: dict[int, list[np.ndarray]] = {}
    for i, S in enumerate(W):
        groups.setdefault(find(i), []).append(S)
    return [np.unique(np.concatenate(v)) for v in groups.values()]


def _solve_window(W, g, f, P, need, cx, vf_ptr, vf_tri, node_limit=200):
    """Values for the vertices W (None when infeasible) minimising
    max |g - f| over W, with vertex types ``need`` on W and its neighbours."""
    adj_ptr, adj_nbr, F, boundary = cx.adj_ptr, cx.adj_nbr, cx.F, cx.boundary
    inW = {int(v): i for i, v in enumerate(W)}
    C = _ball(W, adj_ptr, adj_nbr, 1)  # constrained: W and its ring
    k = len(W)
    z = float(f[W].min())
    eps = 1e-5
    # columns: x (k), t, orientation bits, triangle products
    ncol = [k + 1]
    lo_b, hi_b, integ = [], [], []
    for _ in range(k):
        lo_b.append(-np.inf)
        hi_b.append(np.inf)
        integ.append(0)
    # t: nothing is gained below 1/2, and only a window that gets closer to f is kept (a cutoff for
    # the search)
    cur = float(np.abs(g[W] - f[W]).max()) / P
    lo_b.append(0.5)
    hi_b.append(max(0.5, cur - 1e-6))
    integ.append(0)
    rows, cols, vals, rlo, rhi = [], [], [], [], []

    def row(entries, lo_, hi_):
        r = len(rlo)
        for c_, a_ in entries:
            rows.append(r)
            cols.append(c_)
            vals.append(a_)
        rlo.append(lo_)
        rhi.append(hi_)

    def newcol(lo_, hi_, is_int):
        c_ = ncol[0]
        ncol[0] += 1
        lo_b.append(lo_)
        hi_b.append(hi_)
        integ.append(is_int)
        return c_

    # value bounds (in units of P from z)
    r = max(0.5, cur) + 1e-3  # the box already reached (room for the eps steps)
    for i, v in enumerate(W):
        fv = (f[v] - z) / P
        lo_b[i] = fv - r
        hi_b[i] = fv + r
        row([(i, 1.0), (k, -1.0)], -np.inf, fv)  # x - fv <= t
        row([(i, 1.0), (k, 1.0)], fv, np.inf)  # x - fv >= -t
    ilo = {int(c): (g[c] - z) / P for c in C.tolist()}  # value interval of each vertex, units of P
    ihi = dict(ilo)
    for i, v in enumerate(W.tolist()):
        ilo[v], ihi[v] = lo_b[i], hi_b[i]
    bit: dict[tuple[int, int], int] = {}  # (a, b) with a < b -> column of [b below a], or -1 / -2

    def orient(c_, a_):
        """('c', col, sign) meaning o = col if sign else 1 - col, or ('k', value)."""
        a, b = (c_, a_) if c_ < a_ else (a_, c_)
        col = bit.get((a, b))
        if col is None:
            # col = 1 <=> b below a: g_a - g_b >= e_ab - M1 (1 - col), g_b - g_a >= e_ba - M2 col;
            # the current orientation needs no margin (so the current g is feasible, ulp steps included);
            # an orientation the intervals cannot reach is a constant
            a_low = g[a] < g[b] or (g[a] == g[b] and a < b)
            e_ab = eps if a_low else 0.0
            e_ba = 0.0 if a_low else eps
            fixed = not (a in inW or b in inW)
            can_b_low = fixed or ihi[a] - ilo[b] >= e_ab
            can_a_low = fixed or ihi[b] - ilo[a] >= e_ba
            ea = [(inW[a], 1.0)] if a in inW else []
            eb = [(inW[b], -1.0)] if b in inW else []
            const = (0.0 if a in inW else (g[a] - z) / P) - (0.0 if b in inW else (g[b] - z) / P)
            if fixed:
                col = -1 if a_low else -2
            elif can_b_low and can_a_low:
                col = newcol(0.0, 1.0, 1)
                M1 = e_ab + ihi[b] - ilo[a]
                M2 = e_ba + ihi[a] - ilo[b]
                row(ea + eb + [(col, -M1)], e_ab - M1 - const, np.inf)
                row([(c2, -a2) for c2, a2 in ea + eb] + [(col, M2)], e_ba + const, np.inf)
            elif can_b_low:
                col = -2
                row(ea + eb, e_ab - const, np.inf)
            else:
                col = -1
                row([(c2, -a2) for c2, a2 in ea + eb], e_ba + const, np.inf)
            bit[(a, b)] = col
        if col < 0:  # a constant: -1 for a below b, -2 for b below a
            b_low = col == -2
            return ("k", int(b_low) if c_ == a else 1 - int(b_low))
        return ("c", col, c_ == a)

    def lin(o):
        """o as (entries, constant)."""
        if o[0] == "k":
            return [], float(o[1])
        _, col, pos = o
        return ([(col, 1.0)], 0.0) if pos else ([(col, -1.0)], 1.0)

    for c in C.tolist():
        d = adj_ptr[c + 1] - adj_ptr[c]
        if d == 0:
            continue
        nb = adj_nbr[adj_ptr[c]:adj_ptr[c + 1]].tolist()
        o = {a: orient(c, a) for a in nb}
        tc = int(need[c])
        if tc == -1 or tc == -2:
            want_bit = 0.0 if tc == -1 else 1.0
            for a in nb:
                e, k0 = lin(o[a])
                if not e:
                    if k0 != want_bit:
                        return None
                    continue
                row(e, want_bit - k0, want_bit - k0)
            continue
        entries, const = [], 0.0
        for a in nb:
            e, k0 = lin(o[a])
            entries += e
            const += k0
        if not boundary[c]:  # not a maximum: some bit 0
            row(entries, -np.inf, d - 1 - const)
        for j in range(vf_ptr[c], vf_ptr[c + 1]):
            t = vf_tri[j]
            a, b = [int(w) for w in F[t] if w != c]
            ea, ka = lin(o[a])
            eb, kb = lin(o[b])
            if not ea and not eb:
                const -= ka * kb
            elif not ea or not eb:
                if (ka if not ea else kb):
                    e_other = eb if not ea else ea
                    k_other = kb if not ea else ka
                    entries += [(c2, -a2) for c2, a2 in e_other]
                    const -= k_other
            else:
                p = newcol(0.0, 1.0, 0)
                row(ea + eb + [(p, -1.0)], -np.inf, 1.0 - ka - kb)  # p >= oa + ob - 1
                row(ea + [(p, -1.0)], -ka, np.inf)  # p <= oa
                row(eb + [(p, -1.0)], -kb, np.inf)  # p <= ob
                entries.append((p, -1.0))
        row(entries, tc + 1 - const, tc + 1 - const)
    n = ncol[0]
    from scipy.optimize import Bounds, LinearConstraint, milp  # only where a window needs it (slow to import)

    A = coo_matrix((vals, (rows, cols)), shape=(len(rlo), n)).tocsr()
    cost = np.zeros(n)
    cost[k] = 1.0
    with c_stdout_silenced():  # HiGHS's MIP solver prints debug lines on C stdout, even with disp off
        res = milp(cost, constraints=LinearConstraint(A, rlo, rhi), integrality=np.array(integ),
                   bounds=Bounds(np.array(lo_b), np.array(hi_b)), options={"node_limit": node_limit})
    if res.x is None or res.status not in (0, 1):
        return None
    below = [(b, a) if (col == -2 if col < 0 else res.x[col] > 0.5) else (a, b)
             for (a, b), col in bit.items() if a in inW or b in inW]  # (lower, upper)
    t = float(res.x[k])
    for T in ([0.5] if t <= 0.5 + 1e-6 else []) + [t + 1e-6]:
        x = _values_from_order(W, g, f, P * T, below)
        if x is not None:
            return x
    return None


def _values_from_order(W, g, f, T, below):
    """Values of W as close to f as the strict order ``below`` (pairs (lower,
    upper), each with a vertex of W) and the fixed values outside allow, within
    f +- T (step 2 of :mod:`geoproc.morse.simplify` on the window); None when
    the order has a cycle or does not fit."""
    inW = {int(v): i for i, v in enumerate(W)}
    k = len(W)
    fw = f[W]
    lo = fw - T
    hi = fw + T
    succ = [[] for _ in range(k)]
    indeg = np.zeros(k, np.int64)
    for a, b in below:
        if a in inW and b in inW:
            succ[inW[a]].append(inW[b])
            indeg[inW[b]] += 1
        elif a in inW:
            hi[inW[a]] = min(hi[inW[a]], np.nextafter(g[b], -np.inf))
        else:
            lo[inW[b]] = max(lo[inW[b]], np.nextafter(g[a], np.inf))
    topo = [i for i in range(k) if indeg[i] == 0]
    for i in topo:
        for j in succ[i]:
            indeg[j] -= 1
            if indeg[j] == 0:
                topo.append(j)
    if len(topo) < k:
        return None
    for i in reversed(topo):
        for j in succ[i]:
            hi[i] = min(hi[i], np.nextafter(hi[j], -np.inf))
    x = np.minimum(fw, hi)
    x = np.maximum(x, lo)
    for i in topo:
        if x[i] > hi[i]:
            return None
        for j in succ[i]:
            x[j] = max(x[j], np.nextafter(x[i], np.inf))
    return x


BOX_WIDENING = 1e-9
"""Relative widening of the box f +- P/2 at a vertex on a chain of f that drops by
exactly P (tied data: integer values at an integer P), which the box leaves no
room to order strictly (:func:`geoproc.morse.simplify`'s boxes); it counts as
within P/2."""


TIE_ROUNDING = 1e-6
"""Breaking ties moves a value by units in the last place, excused up to this
fraction of P/2. Where the field's range holds fewer doubles than the mesh
has vertices (a field of range 120 offset by 1e14 has 7,700 doubles for
bunny's 20,900 subdivision vertices), the rises run on for many units of
P, and those are moves past P/2 like any other (they had been excused
whatever their size, and such a run reported none of 20,027)."""


def half_bound_tolerance(f: np.ndarray, half: float, tie_slack=0.0):
    """Largest |g - f| that still counts as within ``half`` (P/2), per vertex
    when ``tie_slack`` is an array.

    Values placed at f +- P/2 carry the rounding of numbers of f's size, which
    exceeds P/2 * 1e-12 when f sits far from 0 (``--field y`` on a mesh moved
    by 1000 units): the tolerance is ``half (1 + BOX_WIDENING) + 64 eps
    max|f|``, so that the test does not depend on the field's offset (nor
    count the widening of boxes on chains that drop by exactly P: on fandisk
    with an integer field at P = 1 it had counted 25 vertices 5e-10 past P/2),
    plus ``tie_slack``, the rise that breaking ties gave a value
    (:func:`geoproc.morse.simplify.strictly_increasing`: a plateau of k
    vertices rises by up to k units in the last place), up to
    :data:`TIE_ROUNDING` of ``half``.
    """
    return (half * (1 + BOX_WIDENING) + 64 * np.finfo(np.float64).eps * float(np.abs(f).max(initial=0.0))
            + np.minimum(tie_slack, TIE_ROUNDING * half))


def _window_score(W, C, g, f, tol, need, cx, vf_ptr, vf_tri):
    wrong = sum(vertex_type(c, g, cx.adj_ptr, cx.adj_nbr, vf_ptr, vf_tri, cx.F, cx.boundary) != need[c]
                for c in C.tolist())
    e = np.abs(g[W] - f[W])
    return wrong, float(e.max()), int((e > tol[W]).sum())


def repair_windows(g, f, P, want, cx, vf_ptr, vf_tri, max_windows: int = -1, radius: int = 1,
                   max_window: int = 300, node_limit: int = 200, slack=0.0) -> tuple[int, int]:
    """Re-solve (in place) the windows around the vertices of g beyond f +- P/2
    or of the wrong type, the farthest from f first.

    Parameters
    ----------
    g : (n,) float64 array
        Current values (every minimum and maximum already the wanted one);
        changed in place.
    f : (n,) float64 array
        The input function.
    P : float
        Persistence threshold (> 0).
    want : (n,) int64 array
        Wanted vertex type (see :mod:`geoproc.morse.refine`).
    cx : SurfaceComplex
    vf_ptr, vf_tri : int64 arrays
        Triangles around each vertex (:func:`geoproc.morse.refine.vertex_faces`).
    max_windows : int
        At most this many windows are solved (-1: all); windows are taken by
        decreasing max |f - g|, those with only a wrong saddle type last.
    radius : int
        Each vertex to repair brings its ``radius``-ring into the window;
        windows that touch are merged.
    max_window : int
        Windows with more vertices are skipped.
    node_limit : int
        Branch-and-bound nodes per window (HiGHS); the best order found by
        then is used.
    slack : (n,) float array or float
        Tie-breaking rise allowed past P/2 (see :func:`half_bound_tolerance`).

    Returns
    -------
    (solved, rewritten) : tuple of int
        Windows solved and windows written back.
    """
    with np.errstate(over="ignore"):
        if not np.isfinite(float(np.ptp(f)) / P):  # a subnormal P: the field's range overflows in its units
            return 0, 0
    half = P / 2.0
    tol = np.broadcast_to(half_bound_tolerance(f, half, slack), f.shape)
    kw = (cx.adj_ptr, cx.adj_nbr, vf_ptr, vf_tri, cx.F, cx.boundary)
    bad = np.abs(g - f) > tol
    windows = [W for W in _windows(bad, cx.adj_ptr, cx.adj_nbr, radius) if len(W) <= max_window]
    if max_windows < 0 or len(windows) < max_windows:  # room for the wrong saddle types too
        bad |= vertex_types(g, *kw) != want
        windows = [W for W in _windows(bad, cx.adj_ptr, cx.adj_nbr, radius) if len(W) <= max_window]
    windows.sort(key=lambda W: -float(np.abs(g[W] - f[W]).max()))
    if max_windows >= 0:
        windows = windows[:max_windows]
    done = 0
    for W in windows:
        C = _ball(W, cx.adj_ptr, cx.adj_nbr, 1)
        now = want.copy()  # the types g has now, on C
        now[C] = [vertex_type(c, g, *kw) for c in C.tolist()]
        for need in (want, now):
            if need is now and not (now[C] != want[C]).any():
                break
            x = _solve_window(W, g, f, P, need, cx, vf_ptr, vf_tri, node_limit)
            if x is None:
                continue
            before = _window_score(W, C, g, f, tol, want, cx, vf_ptr, vf_tri)
            old = g[W].copy()
            g[W] = x
            after = _window_score(W, C, g, f, tol, want, cx, vf_ptr, vf_tri)
            ok = all(vertex_type(c, g, *kw) == need[c] for c in C.tolist())
            close = 1e-9 * P  # max |f - g| values this near count as equal
            better = after[0] < before[0] or (after[0] == before[0] and (
                after[1] < before[1] - close or (after[1] <= before[1] + close and after[2] < before[2])))
            if ok and after[0] <= before[0] and after[1] <= before[1] + close and better:
                done += 1
                break
            g[W] = old
    return len(windows), done
