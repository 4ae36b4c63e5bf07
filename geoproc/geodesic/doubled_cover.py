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
every half-edge, and flipped here (Lawson's algorithm). A function
on the mesh lifts to the cover by taking the same value on both copies; the
Dirichlet energy of the lift is twice the mesh's, so the cover's Laplacian,
mass and face areas, folded onto the mesh's vertices, are halved.

Half-edge ``3 f + c`` is the edge of face f opposite its corner c, running
from corner c + 1 to corner c + 2; ``l[f, c]`` is its length.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.cocircular import TOL, _are_edges, _cocircular, _interior_edges, corner_cotangents
from geoproc.mesh.topology import boundary_edges, edge_key_base, undirected_edge_keys

DELAUNAY_TOL = 1e-9
"""Lawson's flips turn an edge whose opposite cotangents sum below ``-DELAUNAY_TOL``
times the larger of 1 and their sizes; quads within :data:`~geoproc.geodesic.cocircular.TOL`
of cocircular are then set to a canonical diagonal and their weight to zero."""


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


def _corner_cot(l: np.ndarray, f: int, c: int) -> float:
    """Cotangent of the angle at corner c of face f (edge lengths ``l``), by
    the formula of :func:`geoproc.geodesic.cocircular.corner_cotangents`."""
    a, b, e = float(l[f, c]), float(l[f, (c + 1) % 3]), float(l[f, (c + 2) % 3])
    s = 0.5 * (a + b + e)
    area = math.sqrt(max(s * (s - a) * (s - b) * (s - e), 0.0))
    return (b * b + e * e - a * a) / (4.0 * max(area, 1e-300))


def flip_edge(Fi: np.ndarray, l: np.ndarray, twin: np.ndarray, h: int) -> None:
    """Flip half-edge h and its twin in place: triangles (p, a, b) and (q, b, a)
    across edge a-b become (p, a, q) and (q, b, p), the new edge p-q at corner 1
    of both, its length from the quad laid out flat; the twins of the four
    outer edges follow them."""
    t = int(twin[h])
    f, c, g, d = h // 3, h % 3, t // 3, t % 3
    c1, c2, d1, d2 = (c + 1) % 3, (c + 2) % 3, (d + 1) % 3, (d + 2) % 3
    a, b, p, q = Fi[f, c1], Fi[f, c2], Fi[f, c], Fi[g, d]
    ab, bp, pa, aq, qb = (float(x) for x in (l[f, c], l[f, c1], l[f, c2], l[g, d1], l[g, d2]))
    cos1 = min(max((ab * ab + pa * pa - bp * bp) / (2 * ab * pa), -1.0), 1.0)
    cos2 = min(max((ab * ab + aq * aq - qb * qb) / (2 * ab * aq), -1.0), 1.0)
    theta = np.arccos(cos1) + np.arccos(cos2)
    pq = np.sqrt(max(pa * pa + aq * aq - 2 * pa * aq * np.cos(theta), 0.0))
    old = (3 * f + c1, 3 * f + c2, 3 * g + d1, 3 * g + d2)  # edges b-p, p-a, a-q, q-b
    new = (3 * g, 3 * f + 2, 3 * f, 3 * g + 2)  # where each goes
    outer = [int(twin[e]) for e in old]
    Fi[f], l[f] = (p, a, q), (aq, pq, pa)
    Fi[g], l[g] = (q, b, p), (bp, pq, qb)
    twin[3 * f + 1], twin[3 * g + 1] = 3 * g + 1, 3 * f + 1
    for k in range(4):
        o = new[old.index(outer[k])] if outer[k] in old else outer[k]  # an outer twin inside the quad moved too
        twin[new[k]], twin[o] = o, new[k]


def _not_delaunay(ca: float, cb: float, tol: float) -> bool:
    return ca + cb < -tol * max(1.0, abs(ca), abs(cb))


def lawson_flips(Fi: np.ndarray, l: np.ndarray, twin: np.ndarray, tol: float, max_flips: int) -> int:
    """Flip non-Delaunay edges (opposite cotangents summing below ``-tol`` times
    the larger of 1 and their sizes) until none is left, in place. Returns the
    number of flips, or -1 past ``max_flips``.

    The edges are tested all at once first; only those that fail, and the
    edges around each flip, are visited one by one (on a triangulation that
    the mesh's own flips have made Delaunay but at the boundary, a few)."""
    h, t = _edges_once(twin)
    cot = corner_cotangents(l).ravel()
    ca, cb = cot[h], cot[t]
    stack = h[(ca + cb < -tol * np.maximum(1.0, np.maximum(np.abs(ca), np.abs(cb)))) & (h // 3 != t // 3)].tolist()
    flips = 0
    while stack:
        e = stack.pop()
        o = int(twin[e])
        f, g = e // 3, o // 3
        if f == g or not _not_delaunay(_corner_cot(l, f, e % 3), _corner_cot(l, g, o % 3), tol):
            continue
        flip_edge(Fi, l, twin, e)
        flips += 1
        if flips > max_flips:
            return -1
        stack.extend((3 * f, 3 * f + 2, 3 * g, 3 * g + 2))
    return flips


def _edges_once(twin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each edge of a closed triangulation once: half-edge h < twin t."""
    h = np.flatnonzero(twin > np.arange(len(twin)))
    return h, twin[h]


def canonical_cover_diagonals(C, lc, twin, original, F, max_passes: int = 64) -> np.ndarray:
    """Flip the cover's cocircular quads (in place) to the diagonal that is an
    edge of the mesh ``F``, else to the one holding the smallest mesh vertex,
    as :func:`geoproc.geodesic.cocircular.canonical_cocircular_diagonals` does
    on the mesh (vertices compared by the mesh vertex they stand for, so both
    sheets choose alike). Returns (3 m2,) bool, the half-edges of the
    cocircular edges left whose weight, zero in exact arithmetic, came out
    negative: they are given none (a positive one is kept, as a quad within
    the tolerance of cocircular can be a thin strip's only link along it)."""
    keys, base = None, edge_key_base(F)  # F's edges, sorted when a cocircular quad first asks
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
            want[at] = np.where(now == other, np.minimum(p, q) < np.minimum(a, b), other)
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
