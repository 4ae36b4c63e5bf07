"""Discrete differential operators on triangle meshes (libigl conventions).

``L`` is the Laplacian with non-negative off-diagonal weights (for a Delaunay
mesh) and rows summing to zero, so it is negative semi-definite; ``M`` is the
lumped (barycentric / Voronoi-like) vertex mass as an (n,) vector; ``G`` is the
per-face gradient, (3m, n), stacked by coordinate: rows ``[0, m)`` hold the x
components of every face, ``[m, 2m)`` y and ``[2m, 3m)`` z.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.cocircular import canonical_cocircular_diagonals
from geoproc.geodesic.doubled_cover import (
    DELAUNAY_TOL,
    canonical_cover_diagonals,
    doubled_cover,
    folded_laplacian,
    folded_mass,
    lawson_flips,
)
from geoproc.mesh.orientation import consistent_orientation
from geoproc.mesh.topology import boundary_edges, face_areas, repeated_corner_faces, undirected_edge_keys
from geoproc.mesh.topology import mean_edge_length as mean_edge_length  # part of geoproc.geodesic's API

# robust-laplacian's weights that are zero in exact arithmetic come out negative by
# up to this fraction of the largest weight on meshes with needles (cancelling
# cotangents of 1e7); clearing a weight that small changes the solution by about as little
ROBUST_ROUNDING = 1e-10


def cotan_laplacian(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """Cotangent Laplacian (n, n): ``L_ij = (cot a_ij + cot b_ij) / 2``, rows sum to 0.

    Negative semi-definite; off-diagonal weights are negative across
    non-Delaunay edges. Computed by ``igl.cotmatrix``.
    """
    import igl

    return sp.csr_matrix(igl.cotmatrix(V, F))


def infinite_cotan_faces(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Indices of faces whose cotangent weights (``igl.cotmatrix_entries``,
    from edge lengths) are not finite: slivers so thin that their edge lengths
    give zero area although the cross product does not."""
    import igl

    C = igl.cotmatrix_entries(np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F))
    return np.flatnonzero(~np.isfinite(C).all(axis=1))


def flat_within_rounding(Xf: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """(m,) bool: faces whose three values ``Xf`` (m, 3) differ by at most 64
    units in the last place of ``max(max |Xf|, floor)``. Their gradient is a
    rounding difference; normalized, its direction is noise (the heat method
    on a tetrahedron scaled by 1e20 gave 1.04, 0.38 and 0.71 x 1e20 for three
    vertices its symmetry makes equidistant)."""
    a, b, c = Xf[:, 0], Xf[:, 1], Xf[:, 2]  # column-wise: max(axis=1) over 3 is 7x slower
    hi, lo = np.maximum(np.maximum(a, b), c), np.minimum(np.minimum(a, b), c)
    with np.errstate(invalid="ignore"):
        spread = hi - lo
        scale = np.maximum(np.maximum(hi, -lo), floor)  # max |Xf|
    return np.isfinite(scale) & (spread <= 64 * np.finfo(np.float64).eps * scale)


def smallest_angles(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m,) smallest corner angle of each face, in radians (``atan2(|u x v|, u . v)``,
    accurate for needles where the arccosine of a dot product is not).

    ``|u x v|`` is twice the area at every corner, and ``atan2(y, x)`` falls
    as ``x`` grows, so the smallest angle is the one with the largest dot
    product of its two edges: one cross product per face instead of three.
    """
    P = V[F]
    e = np.stack([P[:, 2] - P[:, 1], P[:, 0] - P[:, 2], P[:, 1] - P[:, 0]], axis=1)  # e_c opposite corner c
    twice_area = np.linalg.norm(np.cross(e[:, 1], e[:, 2]), axis=1)
    # corner c lies between edges c+1 and c+2, which leave it as e_{c+2} and -e_{c+1}
    dots = -np.einsum("kcj,kcj->kc", np.roll(e, -1, axis=1), np.roll(e, -2, axis=1))
    # no area: 0 (three corners at one point give dot products of -0.0, and atan2(0, -0.0) = pi)
    return np.where(twice_area == 0, 0.0, np.arctan2(twice_area, dots.max(axis=1)))


def lumped_mass(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n,) Voronoi lumped mass of each vertex (area unit), by ``igl.massmatrix``."""
    import igl

    M = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)
    return np.asarray(M.diagonal(), dtype=np.float64)


def is_edge_manifold_nondegenerate(V: np.ndarray, F: np.ndarray) -> bool:
    """True when there are faces, no edge has more than two and every face has positive area."""
    if len(F) == 0:
        return False
    key = np.sort(undirected_edge_keys(F))
    return bool(not (key[2:] == key[:-2]).any() and (face_areas(V, F) > 0).all())  # no key three times


def intrinsic_delaunay_laplacian(V: np.ndarray, F: np.ndarray,
                                 mollify_factor: float = 1e-5) -> tuple[sp.csr_matrix, np.ndarray]:
    """Laplacian of the intrinsic Delaunay triangulation and its lumped mass.

    On an edge-manifold mesh without zero-area faces:
    :func:`intrinsic_delaunay_mesh` (libigl's edge flips on intrinsic lengths,
    on the doubled cover where an obtuse angle faces a boundary edge) and the
    barycentric mass of that triangulation (``massmatrix_intrinsic``).
    Otherwise: ``robust_laplacian.mesh_laplacian`` (Sharp & Crane 2020: tufted
    cover and mollification, for non-manifold and degenerate input), whose L
    is positive semi-definite and is negated here. Both agree to rounding on
    ordinary meshes. Off-diagonal weights are non-negative: rounding noise below
    1e-14 of the largest weight is set to zero, and below :data:`ROBUST_ROUNDING`
    of it for robust-laplacian (with needles of 1e-7 rad its weights of zero came
    out at -5e-12 of the largest).

    Returns
    -------
    L : (n, n) csr_matrix
        Negative semi-definite, rows sum to zero (the convention of
        :func:`cotan_laplacian`).
    M : (n,) float array
    """
    tri = intrinsic_delaunay_mesh(V, F)
    if tri is not None:
        return tri[0], tri[1]
    import robust_laplacian

    Lp, Mp = robust_laplacian.mesh_laplacian(np.ascontiguousarray(V), np.ascontiguousarray(F),
                                             mollify_factor=mollify_factor)
    L = _drop_rounding_negatives(-sp.csr_matrix(Lp), ROBUST_ROUNDING)
    return L, np.asarray(Mp.diagonal(), dtype=np.float64)


class IntrinsicMesh(NamedTuple):
    """An intrinsic Delaunay triangulation on a mesh's vertices with its operators.

    ``L`` (n, n) its Laplacian (negative semi-definite, non-negative
    off-diagonal weights), ``M`` (n,) its barycentric lumped mass (area unit),
    ``F`` (m, 3) its faces on the mesh's vertices (on a doubled cover a face
    may name a vertex twice, once for each of its images), ``l`` (m, 3) their
    edge lengths, ``l[f, c]`` opposite corner c (length unit), and
    ``face_share`` the part of each face that lies on the mesh: 1, or 0.5 on
    the doubled cover, whose faces cover the mesh twice.
    """

    L: sp.csr_matrix
    M: np.ndarray
    F: np.ndarray
    l: np.ndarray
    face_share: float


def intrinsic_delaunay_mesh(V: np.ndarray, F: np.ndarray, boundary_negatives: bool = False) -> IntrinsicMesh | None:
    """The intrinsic Delaunay triangulation of an edge-manifold mesh with its operators
    (libigl's flips, or on the doubled cover the project's own).

    Cocircular quads get the diagonal that is an edge of ``F``, else the
    shorter one, else the one an intrinsic order of ``V``'s vertices picks
    (:func:`geoproc.geodesic.cocircular.canonical_cocircular_diagonals`), so
    that the triangulation depends neither on the coordinates' rounding nor on
    the numbering of the vertices. Where an obtuse angle faces a boundary edge,
    whose negative weight no flip on the mesh removes, the flips run on the
    mesh's doubled cover instead (:mod:`geoproc.geodesic.doubled_cover`,
    Sharp and Crane's tufted cover), where that edge has a second face and can
    flip; its operators are folded back onto the mesh. On the Delaunay
    triangulation of 1,804 random points, 1,500 of them in a cluster, the heat
    method's mean error fell from 1.5, 6.1 and 8.0 % of the largest distance
    (three source sets) with the mesh's own flips to 0.7, 3.1 and 0.7 %.

    ``boundary_negatives``: where the cover does not apply (a non-orientable
    mesh, such as a Möbius band, whose half-edges do not pair up into a
    cover), return the mesh's own triangulation with its negative boundary
    weights instead of None (the heat method's gradient, divergence and
    Poisson step take them; its heat step then takes
    :func:`intrinsic_delaunay_laplacian`'s).

    Returns
    -------
    IntrinsicMesh or None
        None when the mesh is not edge-manifold, has zero-area faces, or the
        flips leave a negative weight beyond rounding (on an interior edge,
        with ``boundary_negatives``).
    """
    if not is_edge_manifold_nondegenerate(V, F):
        return None
    # faces wound against their neighbours are turned first (the surface is the same):
    # libigl's flips read a face's winding, and on bunny with 50 of its faces stored the
    # other way round they left other weights (up to 12 % of the largest) and negative
    # ones on interior edges with 2,000; the cover pairs each half-edge with one running
    # the other way
    Fo = consistent_orientation(F)[0]
    tri = _flipped_triangulation(V, Fo)
    if tri is None:
        return None
    row, col, w = upper_entries(tri.L)
    negative = w < 0
    if not negative.any():
        return tri
    if not _all_boundary_edges(row[negative], col[negative], tri.F):
        return None
    cover = doubled_cover_mesh(tri.F, tri.l, Fo, len(V), V)
    return cover if cover is not None or not boundary_negatives else tri


def doubled_cover_mesh(Fi: np.ndarray, l: np.ndarray, F: np.ndarray, n: int,
                       V: np.ndarray | None = None) -> IntrinsicMesh | None:
    """The intrinsic Delaunay triangulation of the doubled cover of the
    triangulation ``(Fi, l)`` of the mesh ``F`` (n vertices), folded onto the
    mesh (:mod:`geoproc.geodesic.doubled_cover`); None where the cover does not
    apply or the flips do not end. ``V`` (n, 3), the mesh's positions, order
    the cocircular quads' diagonals that ``F`` leaves undecided
    (:func:`~geoproc.geodesic.doubled_cover.canonical_cover_diagonals`)."""
    cover = doubled_cover(Fi, l, F, n)
    if cover is None:
        return None
    C, lc, twin, original = cover
    if lawson_flips(C, lc, twin, DELAUNAY_TOL, 64 * len(C) + 1024) < 0:
        return None
    zero = canonical_cover_diagonals(C, lc, twin, original, F, V=V)
    L = _drop_rounding_negatives(folded_laplacian(C, lc, original, n, zero))
    if (upper_entries(L)[2] < 0).any() or not np.isfinite(L.data).all():
        return None
    import igl

    M2 = np.asarray(igl.massmatrix_intrinsic(lc, C, igl.MASSMATRIX_TYPE_BARYCENTRIC).diagonal(), dtype=np.float64)
    return IntrinsicMesh(L, folded_mass(M2, original, n), original[C], lc, 0.5)


def _flipped_triangulation(V: np.ndarray, F: np.ndarray) -> IntrinsicMesh | None:
    """The intrinsic Delaunay triangulation of (V, F) with canonical cocircular
    diagonals, negative weights (on boundary edges) kept; None where a weight is not finite."""
    import igl

    Li, l, Fi = igl.intrinsic_delaunay_cotmatrix(np.ascontiguousarray(V), np.ascontiguousarray(F))
    # cocircular quads: the input's diagonal, not the one rounding picks (the mass and the
    # face operators would otherwise change with the mesh's scale and position)
    Fi, l, flips, cocircular = canonical_cocircular_diagonals(Fi, l, F=F, V=V)
    if flips or len(cocircular[0]):
        Li = igl.cotmatrix_intrinsic(l, Fi)
        Li.resize((len(V), len(V)))  # vertices after the last one a face uses
        E, w, single = cocircular  # weights zero in exact arithmetic: negative ones cleared
        below = w < 0
        Li = _without_weights(sp.csr_matrix(Li), E[below], w[below], single[below])
    L = _drop_rounding_negatives(sp.csr_matrix(Li))
    if not np.isfinite(L.data).all():
        return None
    M = igl.massmatrix_intrinsic(l, Fi, igl.MASSMATRIX_TYPE_BARYCENTRIC)
    return IntrinsicMesh(L, np.asarray(M.diagonal(), dtype=np.float64), np.asarray(Fi, dtype=np.int64),
                         np.asarray(l), 1.0)


def _all_boundary_edges(i: np.ndarray, j: np.ndarray, F: np.ndarray) -> bool:
    """Whether every edge (i[k], j[k]) is a boundary edge of the faces F."""
    B = boundary_edges(F)
    if len(B) == 0:
        return False
    n = int(max(F.max(), i.max(), j.max())) + 1
    i, j = np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64)  # keys up to n^2
    key = np.minimum(B[:, 0], B[:, 1]) * n + np.maximum(B[:, 0], B[:, 1])
    return bool(np.isin(np.minimum(i, j) * n + np.maximum(i, j), key).all())


def _without_weights(L: sp.csr_matrix, E: np.ndarray, w: np.ndarray, single: np.ndarray) -> sp.csr_matrix:
    """L without the weights w (k,) of the edges E (k, 2), moved onto the
    diagonal (rows still sum to zero). Where an edge is the only one joining
    its two vertices (``single``) its entry is cleared exactly; where another
    edge joins them too, only w is taken from the entry they share."""
    if len(E) == 0:
        return L
    i, j = E[:, 0], E[:, 1]
    return _moved_to_diagonal(L, i, j, np.where(single, np.asarray(L[i, j]).ravel(), w))


def _moved_to_diagonal(L: sp.csr_matrix, i: np.ndarray, j: np.ndarray, v: np.ndarray) -> sp.csr_matrix:
    """L without the symmetric weights v at (i, j) and (j, i), moved onto the
    diagonal so that rows still sum to zero; explicit zeros dropped."""
    n = L.shape[0]
    fix = sp.coo_matrix((np.concatenate([-v, -v, v, v]),
                         (np.concatenate([i, j, i, j]), np.concatenate([j, i, i, j]))), shape=(n, n))
    L = (L + fix).tocsr()
    L.eliminate_zeros()
    return L


def _drop_rounding_negatives(L: sp.csr_matrix, rounding: float = 1e-14) -> sp.csr_matrix:
    """Zero off-diagonal weights in (-rounding max|L|, 0), moving them onto the diagonal."""
    row, col, w = upper_entries(L)
    tiny = (w < 0) & (w > -rounding * max(1.0, float(np.abs(L.data).max())))
    if tiny.any():
        return _moved_to_diagonal(L, row[tiny], col[tiny], w[tiny])
    L.eliminate_zeros()
    return L


def laplacian_and_mass(V: np.ndarray, F: np.ndarray, kind: str) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(L, M)`` for ``kind`` in :data:`geoproc.geodesic.names.LAPLACIANS` (see the two builders)."""
    if kind == "cotan":
        return cotan_laplacian(V, F), lumped_mass(V, F)
    if kind == "intrinsic-delaunay":
        return intrinsic_delaunay_laplacian(V, F)
    raise ValueError(f"unknown Laplacian {kind!r}")


def upper_entries(L: sp.spmatrix) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows, columns and values of the stored entries above the diagonal
    (``sp.triu(L, 1)``'s, in the order ``coo_matrix(L)`` gives them, without
    building that matrix); ``L`` sparse or dense."""
    C = sp.coo_matrix(L)
    above = C.row < C.col
    return C.row[above], C.col[above], C.data[above]


def negative_offdiagonal_count(L: sp.spmatrix) -> int:
    """Number of undirected edges whose Laplacian weight is negative."""
    C = _canonical(sp.csr_matrix(L))  # a weight stored in parts counts once
    if (C.data < 0).sum() == (C.diagonal() < 0).sum():
        return 0  # the negative entries are all on the diagonal (the usual case, found without the row indices)
    return int((upper_entries(C)[2] < 0).sum())


def face_gradient_matrix(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """(3m, n) per-face gradient of piecewise-linear vertex functions (``igl.grad``)."""
    import igl

    return sp.csr_matrix(igl.grad(V, F))


def face_gradient_coefficients(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(3, m, 3) gradient weights: ``grad f`` on face k, axis a, is
    ``sum_c coef[a, k, c] * f[F[k, c]]`` (unit: 1 / length).

    The gradient of the hat function of corner c is ``N x e_c / |N|^2``, with
    ``N`` the face's (unnormalized) normal and ``e_c`` the edge opposite c,
    oriented counter-clockwise: the weights of ``igl.grad``, formed directly.
    Zero-area faces get zero weights.
    """
    X = V[F]  # (m, 3 corners, 3)
    N = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    nn = np.einsum("ka,ka->k", N, N)
    inv = np.divide(1.0, nn, out=np.zeros_like(nn), where=nn > 0)
    coef = np.empty((3, len(F), 3))
    for c in range(3):
        e = X[:, (c + 2) % 3] - X[:, (c + 1) % 3]
        coef[:, :, c] = (np.cross(N, e) * inv[:, None]).T
    return coef


def stack_gradient_coefficients(coef: np.ndarray, F: np.ndarray, n: int) -> sp.csr_matrix:
    """(k m, n) sparse gradient (rows ``a m + face``, the layout of ``igl.grad``)
    from per-face weights ``coef`` (k, m, 3) on the faces ``F`` (m, 3)."""
    k, m = coef.shape[:2]
    F = np.asarray(F, dtype=np.int64)
    if repeated_corner_faces(F).any():
        # a repeated vertex: its entries are summed into one
        rows = np.broadcast_to((np.arange(k)[:, None] * m + np.arange(m))[:, :, None], coef.shape)
        cols = np.broadcast_to(F[None], coef.shape)
        return sp.csr_matrix((coef.ravel(), (rows.ravel(), cols.ravel())), shape=(k * m, n))
    # three entries per row, put in column order (the canonical CSR that scipy's constructor makes)
    order = np.argsort(F, axis=1, kind="stable")
    cols = np.take_along_axis(F, order, axis=1)
    data = np.take_along_axis(coef, order[None], axis=2)
    indices = np.broadcast_to(cols[None], coef.shape).reshape(-1)
    return sp.csr_matrix((data.reshape(-1), indices, np.arange(0, 3 * k * m + 1, 3)), shape=(k * m, n))


def divergence_matrix(V: np.ndarray, F: np.ndarray, G: sp.spmatrix | None = None) -> sp.csr_matrix:
    """(n, 3m) integrated divergence ``D = -G^T A`` of a per-face vector field.

    With this sign ``D @ (G @ f) == L @ f`` for the cotan Laplacian L, so the
    Poisson problem ``L phi = D X`` recovers ``phi`` from ``X = grad phi``.
    """
    G = face_gradient_matrix(V, F) if G is None else G
    return integrated_divergence(G, face_areas(V, F))


def integrated_divergence(G: sp.spmatrix, area: np.ndarray) -> sp.csr_matrix:
    """(n, k m) ``D = -G^T diag(area)`` for a face gradient ``G`` (k m, n)
    stacked by axis (k axes, m faces, ``area`` (m,) repeated for each axis):
    the transposed gradient with each face's column scaled, formed from G's
    arrays instead of a sparse product."""
    G = sp.csr_matrix(G)
    w = np.repeat(np.tile(area, G.shape[0] // len(area)) if len(area) else np.zeros(0), np.diff(G.indptr))
    with np.errstate(invalid="ignore"):
        data = np.where(w == 0, 0.0, -(G.data * w))  # no area, no entry (libigl's gradient is NaN there)
    D = sp.csc_matrix((data, G.indices, G.indptr), shape=G.shape[::-1]).tocsr()
    D.eliminate_zeros()
    return D


def face_to_vertex_average(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """(n, m) area-weighted average of face values onto vertices (rows sum to 1)."""
    a = face_areas(V, F)
    n, m = len(V), len(F)
    A = sp.csr_matrix((np.repeat(a, 3), (F.reshape(-1), np.repeat(np.arange(m), 3))), shape=(n, m))
    s = np.asarray(A.sum(axis=1)).ravel()
    s[s == 0] = 1.0
    return sp.csr_matrix(sp.diags(1.0 / s) @ A)


SQUARE_SAFE_LOW = 1e-140
"""A row length above this has squares far from underflow (1e-280 against 2.2e-308)."""


def normalized_direction(X: np.ndarray) -> np.ndarray:
    """Rows of ``X`` (m, k) scaled to unit length; zero (or non-finite) rows become 0.

    Rows whose squared length leaves the double range (entries below about
    1e-154, or above 1e154) are first divided by their largest entry: the
    heat method's gradient far from the sources is that small while u is
    still a normal double, and those faces had lost their direction (a
    600-edge strip: largest distance 428 for 600).
    """
    X = np.asarray(X, dtype=np.float64)
    with np.errstate(over="ignore"):  # such rows are taken again below
        norm = np.sqrt(np.add.reduce(X * X, axis=1))  # np.linalg.norm's sum, without its checks
    ok = np.isfinite(norm) & (norm > 0)
    out = np.divide(X, norm[:, None], out=np.zeros_like(X), where=ok[:, None])
    rescale = ~(norm > SQUARE_SAFE_LOW) | (norm == np.inf)
    if rescale.any():
        Y = X[rescale]
        top = np.max(np.abs(Y), axis=1)
        fine = np.isfinite(top) & (top > 0)
        Y = np.divide(Y, top[:, None], out=np.zeros_like(Y), where=fine[:, None])
        length = np.sqrt(np.add.reduce(Y * Y, axis=1))
        out[rescale] = np.divide(Y, length[:, None], out=np.zeros_like(Y), where=fine[:, None])
    return out


def factor_sparse(A: sp.spmatrix):
    """Sparse factorization of a symmetric positive definite matrix, for repeated solves.

    ``M - t L``, the pinned ``-L`` of the Poisson step and their submatrices
    are symmetric positive definite: QDLDL's LDL^T with an AMD ordering
    (``qdldl.Solver``). Returns an object with ``solve(b)``.
    """
    import qdldl

    return qdldl.Solver(upper_triangle_csc(A), upper=True)


def _canonical(C: sp.spmatrix) -> sp.spmatrix:
    """``C`` (csr or csc) with duplicate entries summed and indices sorted: a copy
    when it is not so already (``sum_duplicates`` would change the caller's matrix)."""
    if C.has_canonical_format:
        return C
    C = C.copy()
    C.sum_duplicates()
    return C


def upper_triangle_csc(A: sp.spmatrix) -> sp.csc_matrix:
    """The upper triangle (diagonal included) of a symmetric (n, n) matrix as
    a canonical csc matrix, the input QDLDL factors.

    The entries with row <= column, as ``sp.triu`` keeps them (QDLDL reads
    only those), without its coordinate round trip.
    """
    C = _canonical(sp.csc_matrix(A))
    n = C.shape[0]
    cols = np.repeat(np.arange(n, dtype=C.indices.dtype), np.diff(C.indptr))
    keep = C.indices <= cols
    indptr = np.zeros(n + 1, dtype=C.indptr.dtype)
    np.cumsum(np.bincount(cols[keep], minlength=n), out=indptr[1:])
    return sp.csc_matrix((C.data[keep], C.indices[keep], indptr), shape=(n, n))


def factor_sparse_lu(A: sp.spmatrix):
    """Sparse LU of a non-symmetric matrix with symmetric sparsity and a safe
    diagonal (the Newton Jacobian ``I - P``, an M-matrix): SuperLU with a
    symmetric fill-reducing ordering and diagonal pivots. Returns an object
    with ``solve(b)``.
    """
    from scipy.sparse.linalg import splu

    return splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                options={"SymmetricMode": True})
