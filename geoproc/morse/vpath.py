"""The check that a discrete vector field is a gradient: no closed V-path."""

from __future__ import annotations

import numba
import numpy as np

from geoproc.morse.complex import SurfaceComplex
from geoproc.morse.gradient import DiscreteGradient


@numba.njit(cache=True)
def _find_cycle(succ):
    """A directed cycle in a graph with out-degree <= 2 (``succ`` (N, 2), -1 for
    none), by iterative depth-first search; returns its nodes or an empty array."""
    N = succ.shape[0]
    color = np.zeros(N, np.int8)  # 0 new, 1 on the stack, 2 finished
    stack = np.empty(N, np.int64)
    nxt = np.zeros(N, np.int8)
    for s in range(N):
        if color[s] != 0:
            continue
        top = 0
        stack[0] = s
        color[s] = 1
        nxt[s] = 0
        while top >= 0:
            x = stack[top]
            if nxt[x] >= 2:
                color[x] = 2
                top -= 1
                continue
            y = succ[x, nxt[x]]
            nxt[x] += 1
            if y < 0 or color[y] == 2:
                continue
            if color[y] == 1:
                j = top
                while stack[j] != y:
                    j -= 1
                return stack[j:top + 1].copy()
            top += 1
            stack[top] = y
            color[y] = 1
            nxt[y] = 0
    return np.empty(0, np.int64)


@numba.njit(cache=True)
def _vertex_successors(E, v_e):
    n = v_e.shape[0]
    succ = np.full((n, 2), -1, np.int64)
    for v in range(n):
        e = v_e[v]
        if e >= 0:
            succ[v, 0] = E[e, 1] if E[e, 0] == v else E[e, 0]
    return succ


@numba.njit(cache=True)
def _edge_successors(FE, e_t):
    k = e_t.shape[0]
    succ = np.full((k, 2), -1, np.int64)
    for e in range(k):
        t = e_t[e]
        if t < 0:
            continue
        c = 0
        for j in range(3):
            f = FE[t, j]
            if f != e and e_t[f] >= 0:
                succ[e, c] = f
                c += 1
    return succ


def find_closed_vpath(cx: SurfaceComplex, grad: DiscreteGradient) -> tuple[int, list[int]] | None:
    """Look for a non-trivial closed V-path in a discrete vector field.

    A V-path of dimension 0 runs v0 -> e0 > v1 -> e1 > ... (each vertex to its
    paired edge, then to that edge's other vertex); one of dimension 1 runs
    e0 -> t0 > e1 -> t1 > ... (each edge to its paired triangle, then to another
    edge of that triangle which is itself paired upward). The field is a
    gradient exactly when no such path closes (Forman).

    Also checks that the pairing is consistent (each arrow joins a cell and a
    cofacet, inverses agree); an inconsistent pairing raises ValueError.

    Returns
    -------
    None when there is no closed V-path, else ``(dimension, cells)``: the
    vertices (dimension 0) or edges (dimension 1) along one closed path.
    """
    v_e, e_v, e_t, t_e = grad.vertex_edge, grad.edge_vertex, grad.edge_triangle, grad.triangle_edge
    pv = np.flatnonzero(v_e >= 0)
    if (e_v[v_e[pv]] != pv).any() or ((cx.E[v_e[pv]] == pv[:, None]).sum(axis=1) != 1).any():
        raise ValueError("vertex-edge pairing is inconsistent")
    pe = np.flatnonzero(e_t >= 0)
    if (t_e[e_t[pe]] != pe).any() or ((cx.FE[e_t[pe]] == pe[:, None]).sum(axis=1) != 1).any():
        raise ValueError("edge-triangle pairing is inconsistent")
    if ((e_v >= 0) & (e_t >= 0)).any():
        raise ValueError("an edge is paired both with a vertex and with a triangle")
    cyc = _find_cycle(_vertex_successors(cx.E, v_e))
    if len(cyc):
        return 0, [int(x) for x in cyc]
    cyc = _find_cycle(_edge_successors(cx.FE, e_t))
    if len(cyc):
        return 1, [int(x) for x in cyc]
    return None
