"""Compiled (numba) loops of :mod:`geoproc.mesh.topology`: the fans around each
vertex (used on large meshes) and the corners at each vertex in CSR order."""

from __future__ import annotations

import numba
import numpy as np

from geoproc.union_find import find as _find


@numba.njit(cache=True)
def _union(parent, a, b):
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra != rb:
        parent[ra] = rb


@numba.njit(cache=True, parallel=True)
def fans_from_corners(F, vc_ptr, vc_corner, out):
    """Fans of every vertex from its corners (CSR ``vc_ptr``, ``vc_corner``), into ``out``."""
    for v in numba.prange(out.shape[0]):
        lo = vc_ptr[v]
        d = vc_ptr[v + 1] - lo
        if d == 0:
            out[v] = 0
            continue
        # the other ends of the two edges at each corner; an edge from v to v
        # joins corners of one face, which its other edges join anyway
        other = np.empty(2 * d, dtype=np.int64)
        parent = np.arange(d)
        for i in range(d):
            c = vc_corner[lo + i]
            f = c // 3
            k = c % 3
            other[2 * i] = F[f, (k + 1) % 3]
            other[2 * i + 1] = F[f, (k + 2) % 3]
        # corners on one undirected edge share a fan: pairs of equal ends, by
        # comparing all pairs around a vertex of small valence, else by sorting
        if d <= 16:
            for a in range(2 * d):
                for b in range(a):
                    if other[a] == other[b]:
                        _union(parent, a // 2, b // 2)
        else:
            order = np.argsort(other, kind="mergesort")
            for j in range(1, 2 * d):
                if other[order[j]] == other[order[j - 1]]:
                    _union(parent, order[j] // 2, order[j - 1] // 2)
        count = 0
        for i in range(d):
            if _find(parent, i) == i:
                count += 1
        out[v] = count


@numba.njit(cache=True)
def fill_corners(corners, indptr, out):
    """Corner ids ``3 f + k`` of every vertex into ``out``, in CSR order ``indptr``."""
    pos = indptr[:-1].copy()
    for c in range(corners.shape[0]):
        v = corners[c]
        out[pos[v]] = c
        pos[v] += 1
