"""Where ||f - g|| <= P/2 cannot be met by any vertex function: certificates
independent of the construction.

Any g with exactly the kept minima and maxima of f (vertices compared by
(value, index)) satisfies, for every vertex v, "v has a neighbour below it"
unless v is a kept minimum and "v has a neighbour above it" unless v is a
kept maximum or on the boundary. Two sound arguments on these conditions
alone:

- interval propagation over the boxes [f - h, f + h] (each rule is implied by
  the conditions, so an empty interval proves that no g within h exists);
- an exact mixed-integer program (scipy's HiGHS) on a small window: the
  smallest t such that some g with |g - f| <= t on the window's vertices and
  their neighbours gives every window vertex its wanted status. It drops
  every condition outside the window and relaxes strict inequalities, so it
  is a lower bound on max |f - g| for every g, ours included.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix

from geoproc.mesh import load_mesh
from geoproc.morse import lower_star_persistence, simplify_function, surface_complex
from tests.geoproc.test_morse import mfx


def kept_extrema(cx, f, P):
    """Kept minima and maxima of f (pairs with persistence >= P, and essential)."""
    pf = lower_star_persistence(cx, f)
    pers0 = f[pf.edge_top[pf.min_saddle_edge]] - f[pf.min_vertex]
    pers1 = f[pf.triangle_top[pf.max_triangle]] - f[pf.edge_top[pf.saddle_edge]]
    kmin = np.zeros(len(f), bool)
    kmax = np.zeros(len(f), bool)
    kmin[pf.min_vertex[pers0 >= P]] = True
    kmin[pf.essential_vertices] = True
    kmax[pf.triangle_top[pf.max_triangle[pers1 >= P]]] = True
    kmax[pf.triangle_top[pf.essential_triangles]] = True
    return kmin, kmax


def contradictions(cx, f, h, kmin, kmax):
    """Vertices whose interval becomes empty under the propagation rules."""
    nb = [cx.adj_nbr[cx.adj_ptr[v]:cx.adj_ptr[v + 1]] for v in range(len(f))]
    lo, hi = f - h, f + h
    q, inq, bad = deque(range(len(f))), np.ones(len(f), bool), set()

    def touch(x):
        for y in (x, *nb[x]):
            if not inq[y]:
                inq[y] = True
                q.append(y)

    while q:
        v = q.popleft()
        inq[v] = False
        N = nb[v]
        if len(N) == 0:
            continue
        if kmin[v]:  # every neighbour above
            if hi[N].min() < hi[v]:
                hi[v] = hi[N].min()
                touch(v)
            for w in N[lo[N] < lo[v]]:
                lo[w] = lo[v]
                touch(w)
        else:  # some neighbour below: one of those that can be
            C = N[lo[N] <= hi[v]]
            if len(C) == 0:
                bad.add(v)
                continue
            if lo[C].min() > lo[v]:
                lo[v] = lo[C].min()
                touch(v)
            if len(C) == 1 and hi[C[0]] > hi[v]:
                hi[C[0]] = hi[v]
                touch(C[0])
        if not cx.boundary[v]:
            if kmax[v]:
                if lo[N].max() > lo[v]:
                    lo[v] = lo[N].max()
                    touch(v)
                for w in N[hi[N] > hi[v]]:
                    hi[w] = hi[v]
                    touch(w)
            else:
                C = N[hi[N] >= lo[v]]
                if len(C) == 0:
                    bad.add(v)
                    continue
                if hi[C].max() < hi[v]:
                    hi[v] = hi[C].max()
                    touch(v)
                if len(C) == 1 and lo[C[0]] < lo[v]:
                    lo[C[0]] = lo[v]
                    touch(C[0])
        if lo[v] > hi[v]:
            bad.add(v)
    return sorted(bad)


class _WindowProgram:
    """A window program: the window (``inner`` vertices and their neighbours,
    ``verts``, column ``col[v]`` for g_v, column ``k`` for the bound t, ``big``
    for big-M rows), sparse rows ``lo <= sum a_c z_c <= hi``, and its solve."""

    def __init__(self, cx, f, inner):
        self.nb = lambda v: cx.adj_nbr[cx.adj_ptr[v]:cx.adj_ptr[v + 1]]
        self.f = f
        self.verts = np.unique(np.concatenate([inner] + [self.nb(v) for v in inner]))
        self.col = {int(v): i for i, v in enumerate(self.verts)}
        self.k = len(self.verts)
        self.big = 4.0 * (f[self.verts].max() - f[self.verts].min()) + 1.0
        self.rows, self.cols, self.vals, self.lb, self.ub = [], [], [], [], []

    def row(self, entries, lo_, hi_):
        r = len(self.lb)
        for c, a in entries:
            self.rows.append(r)
            self.cols.append(c)
            self.vals.append(a)
        self.lb.append(lo_)
        self.ub.append(hi_)

    def min_max_change(self, nvar, binary):
        """Columns 0..k-1 the values g, column k the bound t >= |g - f| (minimized),
        the columns ``binary`` 0/1 orientation bits, every column after k in [0, 1]
        (the continuous ones as well). Returns the least t."""
        k = self.k
        for i, v in enumerate(self.verts):  # |g_v - f_v| <= t
            self.row([(i, 1.0), (k, -1.0)], -np.inf, self.f[v])
            self.row([(i, 1.0), (k, 1.0)], self.f[v], np.inf)
        A = coo_matrix((self.vals, (self.rows, self.cols)), shape=(len(self.lb), nvar)).tocsr()
        cost = np.zeros(nvar)
        cost[k] = 1.0
        integ = np.zeros(nvar)
        integ[binary] = 1
        lo_b = np.full(nvar, -np.inf)
        hi_b = np.full(nvar, np.inf)
        lo_b[k:] = 0.0
        hi_b[k + 1:] = 1.0
        res = milp(cost, constraints=LinearConstraint(A, self.lb, self.ub), integrality=integ,
                   bounds=Bounds(lo_b, hi_b))
        assert res.status == 0, res.message
        return float(res.fun)


def window_lower_bound(cx, f, kmin, kmax, inner):
    """Exact smallest max |g - f| over the window (inner vertices and their
    neighbours) for which every inner vertex gets its wanted status."""
    prog = _WindowProgram(cx, f, inner)
    nb, col, k, big, row = prog.nb, prog.col, prog.k, prog.big, prog.row
    nz = [k + 1]  # next binary column; column k is t

    for v in inner:
        for s, keep in ((1.0, kmin[v]), (-1.0, kmax[v])):
            if s < 0 and cx.boundary[v]:
                continue
            if keep:  # s * (g_w - g_v) >= 0 for every neighbour
                for w in nb(v):
                    row([(col[int(w)], s), (col[int(v)], -s)], 0.0, np.inf)
            else:  # some neighbour w with s * (g_v - g_w) >= 0
                zs = []
                for w in nb(v):
                    z = nz[0]
                    nz[0] += 1
                    zs.append(z)
                    row([(col[int(v)], s), (col[int(w)], -s), (z, -big)], -big, np.inf)
                row([(z, 1.0) for z in zs], 1.0, np.inf)
    return prog.min_max_change(nz[0], np.arange(k + 1, nz[0]))


def wanted_types(cx, f, P):
    """Vertex types of a g with exactly the kept critical points of f, each kept
    saddle at its own vertex: -1 kept minimum, -2 kept maximum, k >= 1 the
    number of kept saddle edges (pairs with persistence >= P and essential)
    whose highest vertex it is, 0 regular."""
    kmin, kmax = kept_extrema(cx, f, P)
    pf = lower_star_persistence(cx, f)
    pers0 = f[pf.edge_top[pf.min_saddle_edge]] - f[pf.min_vertex]
    pers1 = f[pf.triangle_top[pf.max_triangle]] - f[pf.edge_top[pf.saddle_edge]]
    kept = np.concatenate([pf.min_saddle_edge[pers0 >= P], pf.saddle_edge[pers1 >= P], pf.essential_edges])
    t = np.bincount(pf.edge_top[kept], minlength=len(f)).astype(np.int64)
    t[kmin] = -1
    t[kmax] = -2
    return t


def typed_window_lower_bound(cx, f, want, inner):
    """Exact smallest max |g - f| over the window (inner vertices and their
    neighbours) for which every inner vertex has the type ``want``: lower link
    of L of its d neighbours in L - T components (T: its triangles with both
    other vertices lower), so L - T = k + 1 for a saddle of multiplicity k
    (k = 0: regular), L < d inside, L = 0 for a minimum, L = d for a maximum.
    One binary per edge (which end is lower), the triangle products
    linearised; order relaxed to <=, so a lower bound for every such g."""
    prog = _WindowProgram(cx, f, inner)
    nb, col, k, big, row = prog.nb, prog.col, prog.k, prog.big, prog.row
    binary = []
    nz = [k + 1]
    bits = {}

    def below(c, a):
        """[a below c] as (entries, constant)."""
        p, q = min(c, a), max(c, a)
        if (p, q) not in bits:  # z = 1: q below p
            z = nz[0]
            nz[0] += 1
            binary.append(z)
            bits[(p, q)] = z
            row([(col[p], 1.0), (col[q], -1.0), (z, -big)], -big, np.inf)
            row([(col[q], 1.0), (col[p], -1.0), (z, big)], 0.0, np.inf)
        z = bits[(p, q)]
        return ([(z, 1.0)], 0.0) if c == p else ([(z, -1.0)], 1.0)

    for v in inner.tolist():
        N = nb(v).tolist()
        if want[v] < 0:
            if want[v] == -2 and cx.boundary[v]:
                continue
            target = 0.0 if want[v] == -1 else 1.0
            for a in N:
                e, c0 = below(v, a)
                row(e, target - c0, target - c0)
            continue
        ent, const = [], 0.0
        for a in N:
            e, c0 = below(v, a)
            ent += e
            const += c0
        if not cx.boundary[v]:
            row(list(ent), -np.inf, len(N) - 1 - const)
        for t in np.flatnonzero((cx.F == v).any(axis=1)):
            a, b = [int(w) for w in cx.F[t] if w != v]
            (ea, ka), (eb, kb) = below(v, a), below(v, b)
            p = nz[0]
            nz[0] += 1
            row(ea + eb + [(p, -1.0)], -np.inf, 1.0 - ka - kb)
            row(ea + [(p, -1.0)], -ka, np.inf)
            row(eb + [(p, -1.0)], -kb, np.inf)
            ent.append((p, -1.0))
        row(ent, want[v] + 1 - const, want[v] + 1 - const)
    return prog.min_max_change(nz[0], binary)


def ball(cx, v, radius):
    S = {int(v)}
    for _ in range(radius):
        S |= {int(w) for u in S for w in cx.adj_nbr[cx.adj_ptr[u]:cx.adj_ptr[u + 1]]}
    return np.array(sorted(S))


def forced_windows(cx, f, P, kmin, kmax):
    """Disjoint radius-2 windows each of which forces max |f - g| > P/2, with
    their lower bounds (as fractions of P)."""
    taken = np.zeros(len(f), bool)
    out = []
    for v in contradictions(cx, f, P / 2, kmin, kmax):
        W = ball(cx, v, 2)
        around = ball(cx, v, 3)
        if taken[around].any():
            continue
        t = window_lower_bound(cx, f, kmin, kmax, W)
        if t > P / 2 * (1 + 1e-9):
            taken[around] = True
            out.append((v, t / P))
    return out


def test_monkey_saddle_window_bound():
    """The hand-made case of test_morse_simplify: P/2 is out of reach; the least
    max |f - g| is (f(M) - f(5)) / 2 (M climbs over its raised neighbour 5),
    below the (f(M) - f(m)) / 2 of draining m and M both across s; ours gets
    there."""
    from tests.geoproc.test_morse_simplify import monkey_saddle_case

    V, F, f, P = monkey_saddle_case()
    cx = surface_complex(F, len(V))
    kmin, kmax = kept_extrema(cx, f, P)
    assert contradictions(cx, f, P / 2, kmin, kmax)
    t = window_lower_bound(cx, f, kmin, kmax, np.arange(len(f)))
    assert t == pytest.approx((f[4] - f[5]) / 2, rel=1e-9)
    s = simplify_function(cx, f, P)  # its exact window reaches the bound (up to 1e-5 P margins)
    assert t <= s.max_abs_change <= t + 1e-4 * P


def test_bunny_half_threshold_infeasible(shared_data):
    """bunny, height + 2% noise, P = 1% of the range: no vertex function with
    exactly the kept extrema stays within P/2; ours reaches the window bound."""
    mesh = load_mesh(shared_data / "meshes" / "bunny.off")
    f = mfx.noisy_height(mesh.V, axis=1, noise=0.02, seed=10)
    P = 0.01 * (f.max() - f.min())
    cx = surface_complex(mesh.F, len(f))
    kmin, kmax = kept_extrema(cx, f, P)
    forced = forced_windows(cx, f, P, kmin, kmax)
    assert len(forced) == 1
    bound = forced[0][1]
    assert bound > 0.8
    s = simplify_function(cx, f, P)
    assert bound * P <= s.max_abs_change <= bound * P * (1 + 1e-6)


def test_armadillo_half_threshold_infeasible(shared_data):
    """armadillo, height + 2% noise, P = 1% of the range: eight disjoint windows
    each force a vertex beyond P/2 (one of them beyond 0.8 P)."""
    mesh = load_mesh(shared_data / "meshes" / "armadillo.obj")
    f = mfx.noisy_height(mesh.V, axis=1, noise=0.02, seed=0)
    P = 0.01 * (f.max() - f.min())
    cx = surface_complex(mesh.F, len(f))
    kmin, kmax = kept_extrema(cx, f, P)
    forced = forced_windows(cx, f, P, kmin, kmax)
    assert len(forced) == 8
    bound = max(t for _, t in forced)
    assert bound > 0.81
    s = simplify_function(cx, f, P)
    assert s.max_abs_change >= bound * P
    # ours: within 0.87 P (0.903 P without the exact windows), and the vertices
    # beyond P/2 are few (at least 8 are forced)
    assert s.max_abs_change <= 0.87 * P
    assert 8 <= len(s.widened_vertices) <= 50


def test_fertility_least_change_for_the_kept_saddles(shared_data):
    """fertility, height + 2% noise, P = 2% of the range: no vertex function with
    exactly the kept critical points, each kept saddle at its own vertex, stays
    within P/2 (a radius-2 window with those vertex types forces 0.561 P, where
    the extrema alone force only 0.47 P); ours reaches that bound."""
    mesh = load_mesh(shared_data / "meshes" / "fertility.off")
    f = mfx.noisy_height(mesh.V, axis=2, noise=0.02, seed=10)
    P = 0.02 * (f.max() - f.min())
    cx = surface_complex(mesh.F, len(f))
    s = simplify_function(cx, f, P)
    v = int(np.argmax(np.abs(s.g - f)))
    want = wanted_types(cx, f, P)
    kmin, kmax = kept_extrema(cx, f, P)
    bound = typed_window_lower_bound(cx, f, want, ball(cx, v, 2))
    assert bound > 0.56 * P
    assert window_lower_bound(cx, f, kmin, kmax, ball(cx, v, 2)) < 0.48 * P
    assert bound <= s.max_abs_change <= bound + 1e-4 * P
