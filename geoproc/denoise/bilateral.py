"""Bilateral filtering of face normals (Zheng et al. 2011; with a guidance field,
Zhang et al. 2015, Eq. 9-11 of the review)."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def _spatial_kernel(indptr, indices, C, A, sigma_s, radius2, W):
    inv_s = -0.5 / (sigma_s * sigma_s)
    for i in numba.prange(C.shape[0]):
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            dx = C[i, 0] - C[j, 0]
            dy = C[i, 1] - C[j, 1]
            dz = C[i, 2] - C[j, 2]
            d2 = dx * dx + dy * dy + dz * dz
            W[p] = 0.0 if d2 > radius2 else A[j] * np.exp(inv_s * d2)


@numba.njit(parallel=True, cache=True)
def _bilateral_kernel(indptr, indices, N, G, W, sigma_r, out):
    m = N.shape[0]
    inv_r = -0.5 / (sigma_r * sigma_r)
    for i in numba.prange(m):
        ax = 0.0
        ay = 0.0
        az = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            if W[p] == 0.0:
                continue
            j = indices[p]
            gx = G[i, 0] - G[j, 0]
            gy = G[i, 1] - G[j, 1]
            gz = G[i, 2] - G[j, 2]
            w = W[p] * np.exp(inv_r * (gx * gx + gy * gy + gz * gz))
            ax += w * N[j, 0]
            ay += w * N[j, 1]
            az += w * N[j, 2]
        norm = np.sqrt(ax * ax + ay * ay + az * az)
        if norm > 0.0:
            out[i, 0] = ax / norm
            out[i, 1] = ay / norm
            out[i, 2] = az / norm
        else:
            out[i, 0] = N[i, 0]
            out[i, 1] = N[i, 1]
            out[i, 2] = N[i, 2]


def spatial_weights(
    C: np.ndarray, A: np.ndarray, neighbors: tuple[np.ndarray, np.ndarray], sigma_s: float,
    radius: float = np.inf,
) -> np.ndarray:
    """Area times spatial Gaussian of every (face, neighbour) pair of the filter.

    Returns
    -------
    (nnz,) float64 aligned with ``neighbors[1]``: ``A_j exp(-|c_i - c_j|^2 / (2 sigma_s^2))``,
    0 where the centroids are farther apart than ``radius``. The positions
    do not change between the passes of one round, so a round computes this once.
    """
    indptr, indices = neighbors
    W = np.empty(len(indices))
    _spatial_kernel(indptr, indices, np.ascontiguousarray(C, dtype=np.float64),
                    np.ascontiguousarray(A, dtype=np.float64), float(sigma_s), float(radius) ** 2, W)
    return W


def bilateral_normal_filter(
    N: np.ndarray,
    C: np.ndarray,
    A: np.ndarray,
    neighbors: tuple[np.ndarray, np.ndarray],
    sigma_s: float,
    sigma_r: float,
    guidance: np.ndarray | None = None,
    radius: float = np.inf,
    spatial: np.ndarray | None = None,
) -> np.ndarray:
    """One pass of the (joint) bilateral filter on face normals.

    ``n_i' = normalize(sum_j A_j W_s(|c_i - c_j|) W_r(|g_i - g_j|) n_j)`` over the
    faces j in the neighbourhood of i, with Gaussian kernels
    ``W(x) = exp(-x^2 / (2 sigma^2))``.

    Parameters
    ----------
    N : (m, 3) float64
        Unit face normals to filter.
    C : (m, 3) float64
        Face centroids.
    A : (m,) float64
        Face areas (weights).
    neighbors : (indptr, indices)
        CSR face neighbourhoods (see :func:`face_ring_csr`).
    sigma_s : float
        Spatial kernel width, in length units.
    sigma_r : float
        Range kernel width on normal differences (unitless, chord length).
    guidance : (m, 3) float64, optional
        Guidance normals for the range kernel; the normals themselves when None
        (the plain bilateral normal filter).
    radius : float
        Only neighbours whose centroid lies within this distance count (a
        geometric ball inside the combinatorial neighbourhood).
    spatial : (nnz,) float64, optional
        :func:`spatial_weights` of ``C``, ``A``, ``neighbors``, ``sigma_s`` and
        ``radius``, to reuse across the passes of a round (those four
        arguments are then not used again).

    Returns
    -------
    (m, 3) float64
        Filtered unit normals.
    """
    G = N if guidance is None else guidance
    W = spatial_weights(C, A, neighbors, sigma_s, radius) if spatial is None else spatial
    out = np.empty_like(N)
    indptr, indices = neighbors
    _bilateral_kernel(indptr, indices, np.ascontiguousarray(N), np.ascontiguousarray(G), W, float(sigma_r), out)
    return out
