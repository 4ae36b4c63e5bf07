"""Discrete differential operators on triangle meshes (libigl conventions).

``L`` is the Laplacian with non-negative off-diagonal weights (for a Delaunay
mesh) and rows summing to zero, so it is negative semi-definite; ``M`` is the
lumped (barycentric / Voronoi-like) vertex mass as an (n,) vector; ``G`` is the
per-face gradient, (3m, n), stacked by coordinate: rows ``[0, m)`` hold the x
components of every face, ``[m, 2m)`` y and ``[2m, 3m)`` z.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

LAPLACIANS = ("cotan", "intrinsic-delaunay")


def mean_edge_length(V: np.ndarray, F: np.ndarray) -> float:
    """Mean length h of the mesh's edges (each undirected edge once), in V's unit."""
    from geoproc.mesh.topology import unique_edges

    E = unique_edges(F)[0]
    return float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean())


def cotan_laplacian(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """Cotangent Laplacian (n, n): ``L_ij = (cot a_ij + cot b_ij) / 2``, rows sum to 0.

    Negative semi-definite; off-diagonal weights are negative across
    non-Delaunay edges. Computed by ``igl.cotmatrix``.
    """
    import igl

    return sp.csr_matrix(igl.cotmatrix(V, F))


def lumped_mass(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n,) Voronoi lumped mass of each vertex (area unit), by ``igl.massmatrix``."""
    import igl

    M = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)
    return np.asarray(M.diagonal(), dtype=np.float64)


def intrinsic_delaunay_laplacian(V: np.ndarray, F: np.ndarray,
                                 mollify_factor: float = 1e-5) -> tuple[sp.csr_matrix, np.ndarray]:
    """Laplacian of the intrinsic Delaunay triangulation and its lumped mass.

    From ``robust_laplacian.mesh_laplacian`` (Sharp & Crane 2020), whose L is
    positive semi-definite: it is negated here to the convention of
    :func:`cotan_laplacian`. Off-diagonal weights are non-negative (rounding
    noise below 1e-14 of the largest weight is set to zero).

    Returns
    -------
    L : (n, n) csr_matrix
    M : (n,) float array
    """
    import robust_laplacian

    Lp, Mp = robust_laplacian.mesh_laplacian(np.ascontiguousarray(V), np.ascontiguousarray(F),
                                             mollify_factor=mollify_factor)
    L = -sp.csr_matrix(Lp)
    off = sp.triu(L, 1, format="coo")
    tiny = (off.data < 0) & (off.data > -1e-14 * max(1.0, float(np.abs(L.data).max())))
    if tiny.any():
        L = L.tolil()
        for i, j in zip(off.row[tiny], off.col[tiny], strict=True):
            L[i, i] += L[i, j]
            L[j, j] += L[j, i]
            L[i, j] = 0.0
            L[j, i] = 0.0
        L = L.tocsr()
    L.eliminate_zeros()
    return L, np.asarray(Mp.diagonal(), dtype=np.float64)


def laplacian_and_mass(V: np.ndarray, F: np.ndarray, kind: str) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(L, M)`` for ``kind`` in :data:`LAPLACIANS` (see the two builders)."""
    if kind == "cotan":
        return cotan_laplacian(V, F), lumped_mass(V, F)
    if kind == "intrinsic-delaunay":
        return intrinsic_delaunay_laplacian(V, F)
    raise ValueError(f"unknown Laplacian {kind!r}")


def negative_offdiagonal_count(L: sp.spmatrix) -> int:
    """Number of undirected edges whose Laplacian weight is negative."""
    off = sp.triu(L, 1, format="coo")
    return int((off.data < 0).sum())


def face_gradient_matrix(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """(3m, n) per-face gradient of piecewise-linear vertex functions (``igl.grad``)."""
    import igl

    return sp.csr_matrix(igl.grad(V, F))


def face_double_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m,) twice the area of each face."""
    return np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def divergence_matrix(V: np.ndarray, F: np.ndarray, G: sp.spmatrix | None = None) -> sp.csr_matrix:
    """(n, 3m) integrated divergence ``D = -G^T A`` of a per-face vector field.

    With this sign ``D @ (G @ f) == L @ f`` for the cotan Laplacian L, so the
    Poisson problem ``L phi = D X`` recovers ``phi`` from ``X = grad phi``.
    """
    G = face_gradient_matrix(V, F) if G is None else G
    a = 0.5 * face_double_areas(V, F)
    return sp.csr_matrix(-(G.T @ sp.diags(np.tile(a, 3))))


def face_to_vertex_average(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """(n, m) area-weighted average of face values onto vertices (rows sum to 1)."""
    a = 0.5 * face_double_areas(V, F)
    n, m = len(V), len(F)
    A = sp.csr_matrix((np.repeat(a, 3), (F.reshape(-1), np.repeat(np.arange(m), 3))), shape=(n, m))
    s = np.asarray(A.sum(axis=1)).ravel()
    s[s == 0] = 1.0
    return sp.csr_matrix(sp.diags(1.0 / s) @ A)


def per_face_vectors(G: sp.spmatrix, f: np.ndarray) -> np.ndarray:
    """(m, 3) gradient vectors of the vertex function ``f`` from ``G`` (3m, n)."""
    g = G @ f
    return g.reshape(3, -1).T


def normalized_direction(X: np.ndarray) -> np.ndarray:
    """Rows of ``X`` (m, 3) scaled to unit length; zero (or non-finite) rows become 0."""
    norm = np.linalg.norm(X, axis=1)
    ok = np.isfinite(norm) & (norm > 0)
    out = np.zeros_like(X)
    out[ok] = X[ok] / norm[ok, None]
    return out


def factor_sparse(A: sp.spmatrix):
    """Sparse LU of a matrix with symmetric sparsity and a safe diagonal.

    For the M-matrices and SPD matrices used here (``M - t L``, pinned ``-L``,
    the log-ODE Jacobian ``I - P``): SuperLU with a symmetric fill-reducing
    ordering and diagonal pivots (no row interchanges), an order of magnitude
    faster than the default partial pivoting. Returns an object with ``solve``.
    """
    from scipy.sparse.linalg import splu

    return splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                options={"SymmetricMode": True})
