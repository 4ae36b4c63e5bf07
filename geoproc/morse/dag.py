"""Topological order of a relation given as arcs, and values in a box that respect it."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def topological_order(A, B, n):
    """Kahn's algorithm on the arcs ``A[i] -> B[i]`` over nodes ``0 .. n-1``.

    Parameters
    ----------
    A, B : (k,) int64 arrays
        Arc tails and heads.
    n : int
        Number of nodes.

    Returns
    -------
    ptr, succ : CSR successor lists (``succ[ptr[a]:ptr[a + 1]]``, in arc order);
    topo : (n,) int64, its first ``count`` entries in topological order;
    count : number of nodes ordered (n unless the arcs have a cycle);
    indeg : (n,) int64 in-degrees left, positive on and after cycles.
    """
    ptr = np.zeros(n + 1, np.int64)
    indeg = np.zeros(n, np.int64)
    for i in range(A.shape[0]):
        ptr[A[i] + 1] += 1
        indeg[B[i]] += 1
    for v in range(n):
        ptr[v + 1] += ptr[v]
    pos = ptr[:-1].copy()
    succ = np.empty(A.shape[0], np.int64)
    for i in range(A.shape[0]):
        succ[pos[A[i]]] = B[i]
        pos[A[i]] += 1
    topo = np.empty(n, np.int64)
    head = 0
    count = 0
    for v in range(n):
        if indeg[v] == 0:
            topo[count] = v
            count += 1
    while head < count:
        a = topo[head]
        head += 1
        for j in range(ptr[a], ptr[a + 1]):
            b = succ[j]
            indeg[b] -= 1
            if indeg[b] == 0:
                topo[count] = b
                count += 1
    return ptr, succ, topo, count, indeg


@numba.njit(cache=True)
def values_in_box(f, half, ptr, succ, topo):
    """Values within ``f +- half`` strictly increasing along every arc, as close to f as the arcs allow.

    A backward pass gives each node the highest value its successors allow
    (``hi <= f + half``, one unit in the last place below each successor's),
    a forward pass the value ``min(f, hi)`` raised to one unit in the last
    place above every predecessor's. When the box is wide enough for every
    chain the result stays in it; otherwise it leaves it (below ``f - half``)
    where a chain does not fit.

    Parameters
    ----------
    f, half : (n,) float64 arrays
        Target values and the half-width of each node's box.
    ptr, succ, topo : from :func:`topological_order` (acyclic: every node in ``topo``).

    Returns
    -------
    (n,) float64 values.
    """
    n = f.shape[0]
    hi = f + half
    for i in range(n - 1, -1, -1):
        a = topo[i]
        for j in range(ptr[a], ptr[a + 1]):
            x = np.nextafter(hi[succ[j]], -np.inf)
            if x < hi[a]:
                hi[a] = x
    g = np.empty(n)
    for v in range(n):
        g[v] = min(f[v], hi[v])
    for i in range(n):
        a = topo[i]
        x = np.nextafter(g[a], np.inf)
        for j in range(ptr[a], ptr[a + 1]):
            b = succ[j]
            if x > g[b]:
                g[b] = x
    return g
