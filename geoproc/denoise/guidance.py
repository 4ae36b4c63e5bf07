"""Guidance normals from the most consistent patch (Zhang et al. 2015)."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def _patch_scores(indptr, indices, edge_nb, N, A, eps, H, M):
    m = N.shape[0]
    for j in numba.prange(m):
        start = indptr[j]
        stop = indptr[j + 1]
        # Phi: largest normal difference between two faces of the patch
        phi = 0.0
        for p in range(start, stop):
            a = indices[p]
            for q in range(p + 1, stop):
                b = indices[q]
                dx = N[a, 0] - N[b, 0]
                dy = N[a, 1] - N[b, 1]
                dz = N[a, 2] - N[b, 2]
                d = np.sqrt(dx * dx + dy * dy + dz * dz)
                if d > phi:
                    phi = d
        # R: largest edge saliency over the sum, on edges inside the patch
        top = 0.0
        total = 0.0
        mx = 0.0
        my = 0.0
        mz = 0.0
        for p in range(start, stop):
            a = indices[p]
            mx += A[a] * N[a, 0]
            my += A[a] * N[a, 1]
            mz += A[a] * N[a, 2]
            for k in range(3):
                b = edge_nb[a, k]
                if b <= a:
                    continue
                inside = False
                for q in range(start, stop):
                    if indices[q] == b:
                        inside = True
                        break
                if not inside:
                    continue
                dx = N[a, 0] - N[b, 0]
                dy = N[a, 1] - N[b, 1]
                dz = N[a, 2] - N[b, 2]
                s = np.sqrt(dx * dx + dy * dy + dz * dz)
                total += s
                if s > top:
                    top = s
        H[j] = phi * top / (eps + total)
        norm = np.sqrt(mx * mx + my * my + mz * mz)
        if norm > 0.0:
            M[j, 0] = mx / norm
            M[j, 1] = my / norm
            M[j, 2] = mz / norm
        else:
            M[j, 0] = N[j, 0]
            M[j, 1] = N[j, 1]
            M[j, 2] = N[j, 2]


@numba.njit(parallel=True, cache=True)
def _pick_patches(indptr, indices, H, M, out):
    m = M.shape[0]
    for i in numba.prange(m):
        best = indices[indptr[i]]
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if H[j] < H[best]:
                best = j
        out[i, 0] = M[best, 0]
        out[i, 1] = M[best, 1]
        out[i, 2] = M[best, 2]


def patch_consistency(
    N: np.ndarray, A: np.ndarray, patches: tuple[np.ndarray, np.ndarray], edge_nb: np.ndarray,
    eps: float = 1e-9,
) -> tuple[np.ndarray, np.ndarray]:
    """Consistency score and mean normal of the patch centred at every face.

    ``H(P) = Phi(P) * R(P)``: Phi is the largest normal difference between two
    faces of P, R the largest edge saliency ``|n_a - n_b|`` over the sum of the
    saliencies of the edges inside P (plus ``eps``). A small H marks a patch
    that is flat, or whose variation comes from one consistent feature.

    Parameters
    ----------
    N : (m, 3) unit face normals; A : (m,) face areas;
    patches : CSR (indptr, indices), the patch of each face (its vertex one-ring);
    edge_nb : (m, 3) edge-adjacent faces (-1 on a boundary).

    Returns
    -------
    H : (m,) float64 scores; M : (m, 3) area-weighted mean unit normal of each patch.
    """
    m = len(N)
    H = np.empty(m)
    M = np.empty((m, 3))
    _patch_scores(patches[0], patches[1], edge_nb, N, A, eps, H, M)
    return H, M


def guidance_normals(
    N: np.ndarray, A: np.ndarray, patches: tuple[np.ndarray, np.ndarray], edge_nb: np.ndarray,
) -> np.ndarray:
    """Guidance normal of every face: the mean normal of the most consistent
    (lowest H) patch among the patches that contain the face.

    Patches are vertex one-rings, so the patches containing face i are those
    centred at the faces of i's own one-ring.

    Returns
    -------
    (m, 3) float64 unit guidance normals.
    """
    H, M = patch_consistency(N, A, patches, edge_nb)
    out = np.empty_like(M)
    _pick_patches(patches[0], patches[1], H, M, out)
    return out
