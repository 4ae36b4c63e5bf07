"""The intrinsic Delaunay triangulation of a mesh's doubled cover, folded back onto the mesh.

An obtuse angle facing a boundary edge gives that edge a negative cotan weight,
and no edge flip on the mesh removes it: a boundary edge has one face only.
The doubled cover glues the mesh to a mirrored copy of itself along the
boundary (Sharp and Crane's tufted cover, "A Laplacian for Nonmanifold
Triangle Meshes", 2020, for a manifold mesh): a closed surface on which every
edge has two faces, so the intrinsic Delaunay flips can turn a boundary edge
too, into an edge that runs from a vertex to its own mirror image.

The cover can join two vertices by two edges (an interior edge between two
boundary vertices and its mirror image), which a vertex-indexed mesh cannot
hold, so the cover is kept as faces, edge lengths and an explicit twin for
every half-edge, and flipped here (Lawson's algorithm, compiled in
:mod:`geoproc.geodesic.cover_flips`, which loads numba only for a mesh
that needs the cover: a Delaunay mesh of a long strip made 130,678 flips,
16 s in Python). A function
on the mesh lifts to the cover by taking the same value on both copies; the
Dirichlet energy of the lift is twice the mesh's, so the cover's Laplacian,
mass and face areas, folded onto the mesh's vertices, are halved.

Half-edge ``3 f + c`` is the edge of face f opposite its corner c, running
from corner c + 1 to corner c + 2; ``l[f, c]`` is its length.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.cocircular import (
    TOL,
    _are_edges,
    _cocircular,
    _interior_edges,
    _LazyRank,
    corner_cotangents,
    other_diagonal_first,
)
from geoproc.mesh.topology import boundary_edges, edge_key_base, undirected_edge_keys

DELAUNAY_TOL = 1e-9
"""Lawson's flips turn an edge whose opposite cotangents sum below ``-DELAUNAY_TOL``
times the larger of 1 and their sizes; quads within :data:`~geoproc.geodesic.cocircular.TOL`
of cocircular are then set to a canonical diagonal, and their weight to zero
where it came out negative (:func:`canonical_cover_diagonals`)."""


def doubled_cover(Fi: np.ndarray, l: np.ndarray, F: np.ndarray, n: int):
    """The doubled cover of a triangulation with boundary, with explicit twins.

    Parameters
    ----------
    Fi : (m, 3) int array, l : (m, 3) float array
        A triangulation of the mesh on its n vertices and its edge lengths
        (the mesh itself, or its intrinsic flips, which keep the boundary).
    F : (k, 3) int array
        The mesh's faces, whose boundary edges must be those of ``Fi``.
    n : int

    Returns
    -------
    (C, lc, twin, original) or None
        ``C`` (2m, 3) the faces of ``Fi``, then their mirror images (the same
        faces on the copies, in reverse order); the copy of an interior vertex
        v is ``n + v``, a boundary vertex is its own copy. ``lc`` (2m, 3)
        their edge lengths, ``twin`` (6m,) the half-edge across each
        half-edge, ``original`` (2n,) the mesh vertex each cover vertex
        stands for. None when the edges of ``Fi`` do not pair up into twins
        and the boundary of ``F`` (an edge from a vertex to itself, a
        non-manifold edge).
    """
    Fi, l = np.asarray(Fi, dtype=np.int64), np.asarray(l, dtype=np.float64)
    m = len(Fi)
    h, t, _, _ = _interior_edges(Fi, l)
    twin = np.full(3 * m, -1, dtype=np.int64)
    twin[h], twin[t] = t, h
    open_ = np.flatnonzero(twin < 0)
    tails, heads = Fi.ravel()[3 * (open_ // 3) + (open_ + 1) % 3], Fi.ravel()[3 * (open_ // 3) + (open_ + 2) % 3]
    B = boundary_edges(F)
    if len(open_) != len(B) or (tails == heads).any() or not len(B):
        return None
    if not np.array_equal(np.unique(np.minimum(tails, heads) * n + np.maximum(tails, heads)),
                          np.unique(np.minimum(B[:, 0], B[:, 1]) * n + np.maximum(B[:, 0], B[:, 1]))):
        return None
    copy = np.arange(n, dtype=np.int64) + n
    copy[tails] = tails
    C = np.concatenate([Fi, copy[Fi][:, ::-1]])
    lc = np.concatenate([l, l[:, ::-1]])
    # half-edge 3 f + c of the mesh is half-edge 3 (m + f) + 2 - c of the mirror
    mirror = lambda e: 3 * (m + e // 3) + 2 - e % 3  # noqa: E731
    cover_twin = np.empty(6 * m, dtype=np.int64)
    cover_twin[:3 * m] = np.where(twin >= 0, twin, mirror(np.arange(3 * m)))
    cover_twin[mirror(np.arange(3 * m))] = np.where(twin >= 0, mirror(np.maximum(twin, 0)), np.arange(3 * m))
    original = np.concatenate([np.arange(n), np.arange(n)])
    return C, lc, cover_twin, original


def lawson_flips(Fi: np.ndarray, l: np.ndarray, twin: np.ndarray, tol: float, max_flips: int) -> int:
    """Flip non-Delaunay edges (opposite cotangents summing below ``-tol`` times
    the larger of 1 and their sizes) until none is left, in place. Returns the
    number of flips, or -1 past ``max_flips``. The edges are tested all at
    once first; the compiled loop (:func:`geoproc.geodesic.cover_flips.lawson_flips`)
    starts from those that fail."""
    from geoproc.geodesic.cover_flips import lawson_flips as compiled

    h, t = _edges_once(twin)
    cot = corner_cotangents(l).ravel()
    ca, cb = cot[h], cot[t]
    start = h[(ca + cb < -tol * np.maximum(1.0, np.maximum(np.abs(ca), np.abs(cb)))) & (h // 3 != t // 3)]
    if not len(start):
        return 0
    return int(compiled(Fi, l, twin, start, float(tol), int(max_flips)))


def _edges_once(twin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each edge of a closed triangulation once: half-edge h < twin t."""
    h = np.flatnonzero(twin > np.arange(len(twin)))
    return h, twin[h]


def canonical_cover_diagonals(C, lc, twin, original, F, max_passes: int = 64, V=None) -> np.ndarray:
    """Flip the cover's cocircular quads (in place) to the diagonal that is an
    edge of the mesh ``F``, else to the shorter one, else to the one holding
    the first mesh vertex by :func:`geoproc.geodesic.cocircular.vertex_rank`
    (of the positions ``V`` and ``F``; by index without ``V``), as
    :func:`geoproc.geodesic.cocircular.canonical_cocircular_diagonals` does
    on the mesh (vertices compared by the mesh vertex they stand for, so both
    sheets choose alike). Returns (3 m2,) bool, the half-edges of the
    cocircular edges left whose weight, zero in exact arithmetic, came out
    negative: they are given none (a positive one is kept, as a quad within
    the tolerance of cocircular can be a thin strip's only link along it)."""
    from geoproc.geodesic.cover_flips import flip_edge

    keys, base = None, edge_key_base(F)  # F's edges, sorted when a cocircular quad first asks
    rank = None  # the mesh vertices' order, likewise
    flat = C.ravel()
    for _ in range(max_passes):
        h, t = _edges_once(twin)
        cot = corner_cotangents(lc).ravel()
        on = _cocircular(cot, h, t, TOL)
        at = np.flatnonzero(on)
        want = np.zeros(len(h), dtype=bool)
        if len(at):
            ha, ta = h[at], t[at]
            a, b = original[flat[3 * (ha // 3) + (ha + 1) % 3]], original[flat[3 * (ha // 3) + (ha + 2) % 3]]
            p, q = original[flat[ha]], original[flat[ta]]
            keys = np.unique(undirected_edge_keys(F)) if keys is None else keys
            now, other = (_are_edges(keys, base, x, y) for x, y in ((a, b), (p, q)))
            want[at] = other
            u = np.flatnonzero(now == other)
            if len(u):
                if rank is None:
                    rank = _LazyRank(V, F, int(original.max()) + 1)
                want[at[u]] = other_diagonal_first(lc, ha[u], ta[u], a[u], b[u], p[u], q[u], rank)
        if not want.any():
            return _negative_halves(twin, h, t, cot, on)
        used = np.zeros(len(C), dtype=bool)
        for e in h[want].tolist():
            f, g = e // 3, twin[e] // 3
            if used[f] or used[g] or f == g:
                continue
            used[f] = used[g] = True
            flip_edge(C, lc, twin, e)
    h, t = _edges_once(twin)
    cot = corner_cotangents(lc).ravel()
    return _negative_halves(twin, h, t, cot, _cocircular(cot, h, t, TOL))


def _negative_halves(twin, h, t, cot, on) -> np.ndarray:
    """(len(twin),) bool: both half-edges of the cocircular edges ``on`` whose
    weight came out negative (a rounding difference from zero)."""
    out = np.zeros(len(twin), dtype=bool)
    below = on & (cot[h] + cot[t] < 0)
    out[h[below]] = out[t[below]] = True
    return out


def folded_laplacian(C, lc, original, n: int, zero: np.ndarray) -> sp.csr_matrix:
    """(n, n) Laplacian on the mesh from the cover's triangulation: ``P^T L2 P / 2``
    with ``L2`` the cover's cotan Laplacian (half-edges in ``zero`` weigh
    nothing) and ``P`` the lift that copies each vertex's value to its images.
    Rows sum to zero; an edge between a vertex and its mirror only adds to the
    diagonal what it takes away from it."""
    w = np.where(zero, 0.0, 0.25 * corner_cotangents(lc).ravel())  # half a cot per half-edge, halved
    flat = C.ravel()
    e = np.arange(len(flat))
    i, j = original[flat[3 * (e // 3) + (e + 1) % 3]], original[flat[3 * (e // 3) + (e + 2) % 3]]
    W = sp.coo_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()
    return sp.csr_matrix(W - sp.diags(np.asarray(W.sum(axis=1)).ravel()))


def folded_mass(M2: np.ndarray, original: np.ndarray, n: int) -> np.ndarray:
    """(n,) vertex mass on the mesh: half the summed mass ``M2`` of each vertex's
    images (cover vertices past ``len(M2)`` have none)."""
    return 0.5 * np.bincount(original[:len(M2)], weights=np.asarray(M2, dtype=np.float64), minlength=n)
