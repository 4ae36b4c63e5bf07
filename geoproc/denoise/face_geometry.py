"""Per-face geometry and face neighbourhoods used by the normal filters.

Conventions: ``V`` (n, 3) float64 vertex positions, ``F`` (m, 3) int64 triangles.
Neighbourhoods are returned as CSR pairs ``(indptr, indices)``: the neighbours of
face ``i`` are ``indices[indptr[i]:indptr[i + 1]]`` (sorted, including ``i``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.mesh.topology import cross_rows, face_corner_edges, row_norms, unique_edges

DEGENERATE_SINE = 1e-10
"""A face whose angle at its first corner has a smaller sine is degenerate for
its normal (:func:`face_normals_and_areas`): its cross product is then at most
1e-10 of the product of the two sides from that corner, and rounding error of
about 1e-16 of it turns the normal by up to 1e-6 radians there."""


STORED_COLLINEAR = 4.0
"""A face whose height over its longest edge is at most this many times the
rounding of the stored coordinates (:func:`stored_rounding`) is collinear as
stored: rounding each of three collinear points by up to d moves the middle one
off the others' line by at most 2 sqrt(3) d."""

DECIMAL_GRID_LIMIT = 1e-3
"""A grid of stored coordinates coarser than this fraction of the mean edge
length is not rounding (integer coordinates of a synthetic mesh are exact)."""


def stored_rounding(V: np.ndarray, F: np.ndarray) -> float:
    """How far rounding to the precision they are stored in may have moved the
    vertices the faces use, in V's length unit:

    - written with a fixed count of decimals (``%.6f``): half the step of that
      decimal grid (5e-7), when values in the largest value's decade use all of them;
    - written with a fixed count of significant digits (``%g``'s six, as the
      shared data's OBJ and OFF files are): half the last digit's step at the
      largest magnitude among the values that use them all (5e-6 for
      coordinates from 1 to 10; a value that happens to be round, such as a
      largest coordinate of exactly 1, does not count);
    - every coordinate a float32 number: half a float32 spacing at the largest
      magnitude;
    - 0 for doubles on no such grid, and for a grid coarser than
      :data:`DECIMAL_GRID_LIMIT` of the mean edge length (exact data, such as
      integer coordinates).

    An edge's midpoint stored that way as a face's third corner (a T-junction
    filler) lies off its segment by that rounding: a sine of 1e-6 where one of
    full double precision has 1e-16, so :data:`DEGENERATE_SINE` alone misses it.
    """
    used = np.zeros(len(V), dtype=bool)
    used[np.asarray(F, dtype=np.int64).reshape(-1)] = True
    x = V[used].reshape(-1)
    top = float(np.abs(x).max(initial=0.0))
    if top == 0.0:
        return 0.0
    a, b = face_corner_edges(V, F)
    limit = DECIMAL_GRID_LIMIT * float(np.concatenate([row_norms(a), row_norms(b)]).mean())
    k = _decimals(x, top)
    if k is not None:
        if 0.5 * 10.0**-k > limit:  # on a grid that coarse the data are exact (integers are float32 numbers too)
            return 0.0
        big = x[np.abs(x) >= 10.0 ** np.floor(np.log10(top))]  # the decade of the largest value
        if k == 0 or _decimals(big, top, k - 1) is None:  # it uses all k decimals: '%.kf'
            return 0.5 * 10.0**-k
    half = _significant_rounding(x)  # (finer decimals needed only by small values: '%g')
    if half is None and top <= float(np.finfo(np.float32).max) and np.array_equal(
            x.astype(np.float32).astype(np.float64), x):
        half = 0.5 * float(np.spacing(np.float32(top)))
    return half if half is not None and half <= limit else 0.0


def _on_grid(x: np.ndarray, scale) -> bool:
    """Whether every ``x * scale`` is an integer (to 1e-6 of one: the rounding of
    a decimal written as the nearest double)."""
    return bool(_on_grid_each(x, scale).all())


def _on_grid_each(x: np.ndarray, scale) -> np.ndarray:
    """(k,) bool: which ``x * scale`` are integers (as :func:`_on_grid`)."""
    with np.errstate(over="ignore", invalid="ignore"):  # subnormals scaled past the double range: no grid
        s = x * scale
        return np.abs(s - np.rint(s)) <= 1e-6


def _decimals(x: np.ndarray, top: float, most: int = 15) -> int | None:
    """The fewest decimals (0 to ``most``) that every value of ``x`` is written
    with, None when none is enough; past 1e12 at ``top`` doubles no longer tell
    a grid point from its neighbours."""
    sample = x[:: max(1, x.size // 997)]  # most data fail on a sample already
    for k in range(most + 1):
        if top * 10.0**k > 1e12:
            return None
        if _on_grid(sample, 10.0**k) and _on_grid(x, 10.0**k):
            return k
    return None


def _significant_rounding(x: np.ndarray) -> float | None:
    """Half the last digit's step, at the largest magnitude among the values that
    use every digit, when all of ``x`` is written with the same count (1 to 12)
    of significant digits; None otherwise."""
    x = x[x != 0]
    if not x.size:
        return None
    e = np.floor(np.log10(np.abs(x)))
    sample = slice(None, None, max(1, x.size // 997))
    with np.errstate(over="ignore", invalid="ignore"):  # subnormals: 10**(d - 1 - e) overflows, no grid
        for d in range(1, 13):
            if _on_grid(x[sample], 10.0 ** (d - 1 - e[sample])) and _on_grid(x, 10.0 ** (d - 1 - e)):
                full = ~_on_grid_each(x, 10.0 ** (d - 2 - e)) if d > 1 else np.ones(x.size, dtype=bool)
                return 0.5 * 10.0 ** float((e[full] if full.any() else e).max() - d + 1)
    return None


def _collinear(a: np.ndarray, b: np.ndarray, rounding: float) -> np.ndarray:
    """(m,) bool: faces with corner edges a, b (m, 3) whose corners lie on a line:
    a sine at the first corner below :data:`DEGENERATE_SINE`, or a height within
    :data:`STORED_COLLINEAR` x ``rounding`` (zero area included)."""
    la, lb = row_norms(a), row_norms(b)
    length = row_norms(cross_rows(a, b))
    flat = length <= DEGENERATE_SINE * la * lb
    if rounding > 0:
        longest = np.maximum(np.maximum(la, lb), row_norms(b - a))
        flat |= length <= STORED_COLLINEAR * rounding * longest
    return flat


def collinear_faces(V: np.ndarray, F: np.ndarray, rounding: float = 0.0) -> np.ndarray:
    """(m,) bool: the faces whose corners lie on a line, the degenerate faces of
    :func:`face_normals_and_areas` (zero area, a sine below
    :data:`DEGENERATE_SINE`, or with ``rounding`` a line as stored): they have no
    normal of their own."""
    return _collinear(*face_corner_edges(V, F), rounding)


def face_normals_and_areas(V: np.ndarray, F: np.ndarray, rounding: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals and face areas, never NaN.

    A degenerate face gets the area-weighted mean normal of the non-degenerate
    faces sharing a vertex with it (or +z when there are none), so that every
    later step sees finite unit vectors; its area stays as computed (0 or
    rounding error), so it carries no weight to speak of. Degenerate: zero area, or a sine
    of the angle at its first corner below :data:`DEGENERATE_SINE` (a midpoint
    of an edge stored as a third corner gives an area of rounding error, whose
    cross product points anywhere), or, with ``rounding`` (:func:`stored_rounding`),
    corners on a line as stored (:data:`STORED_COLLINEAR`).

    Returns
    -------
    N : (m, 3) float64
        Unit normals (counter-clockwise orientation).
    A : (m,) float64
        Areas in squared length units.
    """
    a, b = face_corner_edges(V, F)
    cross = cross_rows(a, b)
    length = row_norms(cross)
    A = 0.5 * length
    good = ~_collinear(a, b, rounding) if rounding > 0 else length > DEGENERATE_SINE * row_norms(a) * row_norms(b)
    N = np.zeros_like(cross)
    N[good] = cross[good] / length[good, None]
    if not good.all():
        bad = np.flatnonzero(~good)
        ring = face_vertex_ring(F, len(V))
        R = ring[bad]
        fill = R @ np.where(good[:, None], cross, 0.0)  # area-weighted sums of neighbour normals (times 2)
        norm = np.linalg.norm(fill, axis=1)
        fill = np.where(norm[:, None] > 0, fill / np.maximum(norm, 1e-300)[:, None], [0.0, 0.0, 1.0])
        N[bad] = fill
    return N, A


def collinear_middles(V: np.ndarray, F: np.ndarray,
                      rounding: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The middle corners of the degenerate faces whose three corners lie on a
    line (:data:`DEGENERATE_SINE`; with ``rounding``, also on a line as stored,
    :data:`STORED_COLLINEAR`), such as T-junction fillers: an edge's
    midpoint stored as a face's third corner.

    Returns
    -------
    mid, a, b : (k,) int arrays
        For each such face, the corner between the other two and the ends of
        its longest edge (faces with coincident corners are left out).
    t : (k,) float array
        Where ``mid`` lies on the segment, ``V[mid] = V[a] + t (V[b] - V[a])``.
    """
    e1, e2 = face_corner_edges(V, F)
    bad = np.flatnonzero(_collinear(e1, e2, rounding))
    if not len(bad):
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty, np.zeros(0)
    Fb = F[bad]
    length = np.stack([row_norms(V[Fb[:, (c + 2) % 3]] - V[Fb[:, (c + 1) % 3]]) for c in range(3)], axis=1)
    c = np.argmax(length, axis=1)  # the corner opposite the longest edge lies between its ends
    r = np.arange(len(Fb))
    mid, a, b = Fb[r, c], Fb[r, (c + 1) % 3], Fb[r, (c + 2) % 3]
    ok = (length[r, c] > 0) & (length[r, (c + 1) % 3] > 0) & (length[r, (c + 2) % 3] > 0)
    mid, a, b = mid[ok], a[ok], b[ok]
    t = row_norms(V[mid] - V[a]) / row_norms(V[b] - V[a])
    return mid, a, b, t


def keep_on_segments(X: np.ndarray, middles, fixed: np.ndarray | None = None) -> np.ndarray:
    """``X`` with each collinear middle corner (:func:`collinear_middles`) put
    back on the segment between the other two, where it was in the input, so
    that a T-junction filler stays flat (fitted to its real faces alone, such
    a vertex left its edge and the filler opened into a fin). Vertices that
    are ``fixed`` stay."""
    mid, a, b, t = middles
    if not len(mid):
        return X
    X = X.copy()
    for i, j, k, s in zip(mid.tolist(), a.tolist(), b.tolist(), t.tolist(), strict=True):
        if fixed is None or not fixed[i]:
            X[i] = X[j] + s * (X[k] - X[j])
    return X


def on_segments_as_stored(V: np.ndarray, F: np.ndarray, fixed: np.ndarray | None = None) -> np.ndarray:
    """``V`` with the middle corner of every face collinear as stored
    (:func:`stored_rounding`) put on the segment between the other two, where
    the file's rounding had moved it off; ``V`` itself when the coordinates are
    full doubles. Six-decimal OBJ or float32 PLY midpoints had read as real
    slivers (sine 1e-6), which the fit opened into fins. Vertices that are
    ``fixed`` ((n,) bool; pinned boundary vertices) stay."""
    rounding = stored_rounding(V, F)
    return keep_on_segments(V, collinear_middles(V, F, rounding), fixed) if rounding > 0 else V


def face_aspect(V: np.ndarray, F: np.ndarray, N: np.ndarray | None = None) -> np.ndarray:
    """(m,) each triangle's height over its longest edge, ``2 A / l_max^2``:
    sqrt(3)/2 for an equilateral triangle, near 0 for a sliver or a needle
    (and 0 for a face whose corners coincide).

    With ``N`` ((m, 3) unit normals), of the triangle projected onto the plane
    normal to ``N[f]``: the shape in the surface when ``N`` is a smooth
    estimate of it and the corners are displaced along it (noise along the
    normals turns a needle into a fat face; its projection stays a needle).
    """
    E = [V[F[:, (c + 1) % 3]] - V[F[:, c]] for c in range(3)]
    if N is not None:
        E = [e - np.einsum("ij,ij->i", e, N)[:, None] * N for e in E]
    l2 = np.max([np.einsum("ij,ij->i", e, e) for e in E], axis=0)
    twice_area = row_norms(np.cross(E[0], -E[2]))
    return np.where(l2 > 0, twice_area / np.where(l2 > 0, l2, 1.0), 0.0)


def face_centroids(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m, 3) triangle centroids (a sum of three gathers: ``V[F].mean(axis=1)``
    took eight times as long on a 70k-face mesh)."""
    return (V[F[:, 0]] + V[F[:, 1]] + V[F[:, 2]]) / 3.0


def face_vertex_ring(F: np.ndarray, n: int) -> sp.csr_matrix:
    """(m, m) 0/1 CSR matrix: faces sharing at least one vertex (diagonal included)."""
    m = len(F)
    FV = sp.csr_matrix((np.ones(3 * m), (np.repeat(np.arange(m), 3), F.reshape(-1))), shape=(m, n))
    R = (FV @ FV.T).tocsr()
    R.data[:] = 1.0
    R.sort_indices()
    return R


def face_ring_csr(F: np.ndarray, n: int, rings: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Faces within ``rings`` vertex rings of each face, as CSR ``(indptr, indices)``.

    ``rings=1`` gives the faces sharing a vertex with the face (its one-ring
    patch, the face itself included); each further ring grows the set by the
    vertex ring of every member.
    """
    R = face_vertex_ring(F, n)
    P = R
    for _ in range(rings - 1):
        P = (P @ R).tocsr()
        P.data[:] = 1.0
    P.sort_indices()
    return P.indptr.astype(np.int64), P.indices.astype(np.int64)


def face_edge_neighbors(F: np.ndarray) -> np.ndarray:
    """(m, 3) edge-adjacent face across each corner's outgoing edge; -1 on a boundary.

    Assumes an edge-manifold mesh (at most two faces per edge).
    """
    m = len(F)
    _, edge_of, _ = unique_edges(F)
    order = np.argsort(edge_of, kind="stable")
    e_sorted = edge_of[order]
    same = e_sorted[1:] == e_sorted[:-1]
    h1, h2 = order[:-1][same], order[1:][same]
    out = np.full(3 * m, -1, dtype=np.int64)
    out[h1] = h2 // 3
    out[h2] = h1 // 3
    return out.reshape(m, 3)


def vertex_face_incidence(F: np.ndarray, n: int) -> sp.csr_matrix:
    """(n, m) 0/1 CSR matrix: vertex v is a corner of face f."""
    m = len(F)
    return sp.csr_matrix((np.ones(3 * m), (F.reshape(-1), np.repeat(np.arange(m), 3))), shape=(n, m))


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n, 3) area-weighted unit vertex normals (zero for unreferenced vertices)."""
    N, A = face_normals_and_areas(V, F)
    W = vertex_face_incidence(F, len(V)) @ (N * np.maximum(A, 1e-300)[:, None])
    norm = np.linalg.norm(W, axis=1, keepdims=True)
    return np.where(norm > 0, W / np.maximum(norm, 1e-300), 0.0)
