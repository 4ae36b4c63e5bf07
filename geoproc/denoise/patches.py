"""Fixed-size face patches, for matrices built from neighbourhoods."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def _nearest_in_rows(indptr, indices, C, k, out):
    m = C.shape[0]
    for i in numba.prange(m):
        start = indptr[i]
        cnt = indptr[i + 1] - start
        d = np.empty(cnt)
        for p in range(cnt):
            j = indices[start + p]
            dx = C[i, 0] - C[j, 0]
            dy = C[i, 1] - C[j, 1]
            dz = C[i, 2] - C[j, 2]
            d[p] = dx * dx + dy * dy + dz * dz
        order = np.argsort(d)
        for q in range(k):
            out[i, q] = indices[start + order[q]] if q < cnt else i


def nearest_faces_in_ring(C: np.ndarray, ring: tuple[np.ndarray, np.ndarray], k: int) -> np.ndarray:
    """(m, k) int64: the k faces of each face's neighbourhood nearest to it by
    centroid distance, the face itself first; rows with fewer than k neighbours
    are padded with the face itself.

    Parameters
    ----------
    C : (m, 3) face centroids; ring : CSR (indptr, indices) neighbourhoods
    (including the face); k : patch size.
    """
    out = np.empty((len(C), k), dtype=np.int64)
    _nearest_in_rows(ring[0], ring[1], np.ascontiguousarray(C), int(k), out)
    return out
