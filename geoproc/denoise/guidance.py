"""Guidance normals from the most consistent patch (Zhang et al. 2015)."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _patch_edge_lists(indptr, indices, edge_nb):
    """Interior edges of every patch, as CSR of half-edge ids ``3 a + k`` (the
    edge between face a and its neighbour ``edge_nb[a, k]`` > a), in the order
    of the patch's faces."""
    m = indptr.shape[0] - 1
    eptr = np.zeros(m + 1, dtype=np.int64)
    for sweep in range(2):
        out = np.empty(eptr[m] if sweep else 0, dtype=np.int64)
        for j in range(m):
            start = indptr[j]
            stop = indptr[j + 1]
            pos = eptr[j]
            cnt = 0
            for p in range(start, stop):
                a = indices[p]
                for k in range(3):
                    b = edge_nb[a, k]
                    if b <= a:
                        continue
                    # patch indices are sorted: binary search for b
                    lo = start
                    hi = stop
                    while lo < hi:
                        mid = (lo + hi) // 2
                        if indices[mid] < b:
                            lo = mid + 1
                        else:
                            hi = mid
                    if lo < stop and indices[lo] == b:
                        if sweep:
                            out[pos + cnt] = 3 * a + k
                        cnt += 1
            if not sweep:
                eptr[j + 1] = eptr[j] + cnt
    return eptr, out


@numba.njit(parallel=True, cache=True)
def _edge_saliency(N, edge_nb, S):
    """``S[3 a + k] = |n_a - n_b|`` for the neighbour b = edge_nb[a, k] > a."""
    for a in numba.prange(N.shape[0]):
        for k in range(3):
            b = edge_nb[a, k]
            if b <= a:
                S[3 * a + k] = 0.0
                continue
            dx = N[a, 0] - N[b, 0]
            dy = N[a, 1] - N[b, 1]
            dz = N[a, 2] - N[b, 2]
            S[3 * a + k] = np.sqrt(dx * dx + dy * dy + dz * dz)


@numba.njit(parallel=True, cache=True)
def _patch_scores(indptr, indices, eptr, eids, S, N, A, eps, H, M):
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
                d = dx * dx + dy * dy + dz * dz
                if d > phi:
                    phi = d
        phi = np.sqrt(phi)
        # R: largest edge saliency over the sum, on edges inside the patch
        top = 0.0
        total = 0.0
        for e in range(eptr[j], eptr[j + 1]):
            s = S[eids[e]]
            total += s
            if s > top:
                top = s
        mx = 0.0
        my = 0.0
        mz = 0.0
        for p in range(start, stop):
            a = indices[p]
            mx += A[a] * N[a, 0]
            my += A[a] * N[a, 1]
            mz += A[a] * N[a, 2]
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


def patch_interior_edges(
    patches: tuple[np.ndarray, np.ndarray], edge_nb: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Edges inside every patch (both faces in the patch), from the topology alone.

    Parameters
    ----------
    patches : CSR (indptr, indices) with sorted rows, the faces of each patch;
    edge_nb : (m, 3) edge-adjacent faces (-1 on a boundary).

    Returns
    -------
    CSR (indptr, ids): the edges of patch j are ``ids[indptr[j]:indptr[j + 1]]``,
    each the half-edge id ``3 a + k`` of the edge between face a and its
    neighbour ``edge_nb[a, k] > a``.
    """
    return _patch_edge_lists(patches[0], patches[1], np.ascontiguousarray(edge_nb, dtype=np.int64))


def patch_consistency(
    N: np.ndarray, A: np.ndarray, patches: tuple[np.ndarray, np.ndarray], edge_nb: np.ndarray,
    eps: float = 1e-9, interior_edges: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Consistency score and mean normal of the patch centred at every face.

    ``H(P) = Phi(P) * R(P)``: Phi is the largest normal difference between two
    faces of P, R the largest edge saliency ``|n_a - n_b|`` over the sum of the
    saliencies of the edges inside P (plus ``eps``). A small H marks a patch
    that is flat, or whose variation comes from one consistent feature.

    Parameters
    ----------
    N : (m, 3) unit face normals; A : (m,) face areas;
    patches : CSR (indptr, indices), the patch of each face (its vertex one-ring, sorted);
    edge_nb : (m, 3) edge-adjacent faces (-1 on a boundary);
    interior_edges : the output of :func:`patch_interior_edges` for these
    patches (computed when None; pass it to reuse it across calls).

    Returns
    -------
    H : (m,) float64 scores; M : (m, 3) area-weighted mean unit normal of each patch.
    """
    N = np.ascontiguousarray(N, dtype=np.float64)
    edge_nb = np.ascontiguousarray(edge_nb, dtype=np.int64)
    eptr, eids = patch_interior_edges(patches, edge_nb) if interior_edges is None else interior_edges
    m = len(N)
    S = np.empty(3 * m)
    _edge_saliency(N, edge_nb, S)
    H = np.empty(m)
    M = np.empty((m, 3))
    _patch_scores(patches[0], patches[1], eptr, eids, S, N, np.ascontiguousarray(A, dtype=np.float64), eps, H, M)
    return H, M


def guidance_normals(
    N: np.ndarray, A: np.ndarray, patches: tuple[np.ndarray, np.ndarray], edge_nb: np.ndarray,
    interior_edges: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Guidance normal of every face: the mean normal of the most consistent
    (lowest H) patch among the patches that contain the face.

    Patches are vertex one-rings, so the patches containing face i are those
    centred at the faces of i's own one-ring. ``interior_edges``: see
    :func:`patch_consistency`.

    Returns
    -------
    (m, 3) float64 unit guidance normals.
    """
    H, M = patch_consistency(N, A, patches, edge_nb, interior_edges=interior_edges)
    out = np.empty_like(M)
    _pick_patches(patches[0], patches[1], H, M, out)
    return out
