"""The cell complex of a triangle mesh: vertices, edges, triangles and the
incidences the Morse algorithms walk."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from geoproc.errors import InputError
from geoproc.mesh.topology import repeated_corner_faces


@dataclass
class SurfaceComplex:
    """Vertices, edges and triangles of a triangle mesh, with incidences.

    Attributes
    ----------
    n : int
        Number of vertices.
    F : (m, 3) int64 array
        Triangles.
    E : (k, 2) int64 array
        Edges, ``E[:, 0] < E[:, 1]``, sorted lexicographically.
    FE : (m, 3) int64 array
        ``FE[t, j]`` is the edge from ``F[t, j]`` to ``F[t, (j + 1) % 3]``.
    ET : (k, 2) int64 array
        The one or two triangles of each edge; ``ET[e, 1] = -1`` on the boundary.
    adj_ptr, adj_nbr, adj_edge : int64 arrays
        Vertex adjacency in CSR form: the neighbours of vertex ``v`` are
        ``adj_nbr[adj_ptr[v]:adj_ptr[v + 1]]`` and ``adj_edge`` holds the edge
        joining them.
    boundary : (n,) bool array
        Vertices on a boundary edge.
    """

    n: int
    F: np.ndarray
    E: np.ndarray
    FE: np.ndarray
    ET: np.ndarray
    adj_ptr: np.ndarray
    adj_nbr: np.ndarray
    adj_edge: np.ndarray
    boundary: np.ndarray

    @property
    def n_edges(self) -> int:
        return len(self.E)

    @property
    def n_faces(self) -> int:
        return len(self.F)

    @property
    def euler_characteristic(self) -> int:
        """V - E + F."""
        return int(self.n - len(self.E) + len(self.F))


@numba.njit(cache=True)
def _build_edges(F, n):
    m = F.shape[0]
    H = 3 * m
    cnt = np.zeros(n + 1, np.int64)
    for h in range(H):
        a = F[h // 3, h % 3]
        b = F[h // 3, (h % 3 + 1) % 3]
        cnt[min(a, b) + 1] += 1
    ptr = np.cumsum(cnt)
    fill = ptr[:-1].copy()
    hi = np.empty(H, np.int64)
    hid = np.empty(H, np.int64)
    for h in range(H):
        a = F[h // 3, h % 3]
        b = F[h // 3, (h % 3 + 1) % 3]
        lo = min(a, b)
        hi[fill[lo]] = max(a, b)
        hid[fill[lo]] = h
        fill[lo] += 1
    # sort each bucket by hi, stably (buckets are vertex degrees: insertion sort, or a merge
    # sort past 32: a vertex of 100k faces had cost 22 s in insertion sort)
    n_edges = 0
    for v in range(n):
        s, t = ptr[v], ptr[v + 1]
        if t - s > 32:
            order = np.argsort(hi[s:t], kind="mergesort")
            hi[s:t] = hi[s:t][order]
            hid[s:t] = hid[s:t][order]
        for i in range(s + 1, t):
            x, y = hi[i], hid[i]
            j = i - 1
            while j >= s and hi[j] > x:
                hi[j + 1] = hi[j]
                hid[j + 1] = hid[j]
                j -= 1
            hi[j + 1] = x
            hid[j + 1] = y
        for i in range(s, t):
            if i == s or hi[i] != hi[i - 1]:
                n_edges += 1
    E = np.empty((n_edges, 2), np.int64)
    FE = np.empty((m, 3), np.int64)
    ET = np.full((n_edges, 2), -1, np.int64)
    too_many = -1
    e = -1
    for v in range(n):
        for i in range(ptr[v], ptr[v + 1]):
            if i == ptr[v] or hi[i] != hi[i - 1]:
                e += 1
                E[e, 0] = v
                E[e, 1] = hi[i]
            h = hid[i]
            FE[h // 3, h % 3] = e
            if ET[e, 0] == -1:
                ET[e, 0] = h // 3
            elif ET[e, 1] == -1:
                ET[e, 1] = h // 3
            elif too_many == -1:
                too_many = e
    # vertex adjacency
    deg = np.zeros(n + 1, np.int64)
    for k in range(n_edges):
        deg[E[k, 0] + 1] += 1
        deg[E[k, 1] + 1] += 1
    adj_ptr = np.cumsum(deg)
    pos = adj_ptr[:-1].copy()
    adj_nbr = np.empty(2 * n_edges, np.int64)
    adj_edge = np.empty(2 * n_edges, np.int64)
    boundary = np.zeros(n, np.bool_)
    for k in range(n_edges):
        a, b = E[k, 0], E[k, 1]
        adj_nbr[pos[a]] = b
        adj_edge[pos[a]] = k
        pos[a] += 1
        adj_nbr[pos[b]] = a
        adj_edge[pos[b]] = k
        pos[b] += 1
        if ET[k, 1] == -1:
            boundary[a] = True
            boundary[b] = True
    return E, FE, ET, adj_ptr, adj_nbr, adj_edge, boundary, too_many


def require_distinct_corners(F: np.ndarray, path: str | None = None) -> None:
    """Raise InputError naming the first triangle of ``F`` (m, 3) that repeats a vertex."""
    rep = repeated_corner_faces(F)
    if rep.any():
        raise InputError(path, f"triangle {int(np.flatnonzero(rep)[0])} repeats a vertex")


def canonical_faces(F: np.ndarray) -> np.ndarray:
    """``F`` (m, 3) with each triangle's corners in increasing order and the
    triangles in lexicographic order: the same array however the input ordered
    its faces and their corners, and whichever way it wound them (the complex
    needs no orientation; rotating the corners but keeping the winding had let
    a mesh with every face reversed give other exact windows, camelhead's
    values moving by up to 0.42 of the field's range)."""
    G = np.sort(np.asarray(F, dtype=np.int64).reshape(-1, 3), axis=1)
    return np.ascontiguousarray(G[np.lexsort((G[:, 2], G[:, 1], G[:, 0]))])


def surface_complex(F: np.ndarray, n: int, path: str | None = None) -> SurfaceComplex:
    """Build the edges and incidences of a triangle mesh.

    Parameters
    ----------
    F : (m, 3) int array
        Triangles of a mesh whose edges each have one or two triangles
        (check vertex manifoldness beforehand with
        :func:`geoproc.mesh.validate.require_manifold`).
    n : int
        Number of vertices (unreferenced vertices become isolated minima;
        :func:`geoproc.morse.morse_simplify` leaves them out first).
    path : str, optional
        File name used in error messages.

    Raises
    ------
    InputError
        A triangle repeats a vertex, or an edge has more than two triangles.
    """
    F = np.ascontiguousarray(F, dtype=np.int64).reshape(-1, 3)
    require_distinct_corners(F, path)
    E, FE, ET, ap, an, ae, bnd, bad = _build_edges(F, int(n))
    if bad >= 0:
        raise InputError(
            path, f"non-manifold: edge {int(E[bad, 0])}-{int(E[bad, 1])} has more than two faces"
        )
    return SurfaceComplex(int(n), F, E, FE, ET, ap, an, ae, bnd)
