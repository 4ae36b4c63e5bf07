"""Orderings that put points close in space close in memory.

The mesh kernels visit, for every face, the faces and vertices around it. On
a mesh stored in an arbitrary order those neighbours lie far apart in memory,
and each visit is a cache miss: on a loop-subdivided armadillo (346k faces,
as ``igl.upsample`` stores them) one guidance pass of the denoiser took 0.29 s
and one filter pass 0.12 s, and 0.16 s and 0.08 s once faces and vertices
were renumbered along a Z-order curve.
"""

from __future__ import annotations

import numpy as np

MORTON_BITS = 21
"""Bits per axis of the Z-order key (3 x 21 = 63 bits: one int64)."""


def _spread_bits(q: np.ndarray) -> np.ndarray:
    """(k,) uint64 with bit b of ``q`` (< 2**21) moved to bit 3b."""
    x = q.astype(np.uint64) & np.uint64(0x1FFFFF)
    x = (x | (x << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x1249249249249249)
    return x


def morton_order(P: np.ndarray) -> np.ndarray:
    """(k,) int64 permutation that sorts the points ``P`` (k, 3) along a
    Z-order (Morton) curve over their bounding box, 2**21 cells a side.

    Points in the same cell keep their relative order (a stable sort);
    non-finite points count as lying in the first cell.
    """
    P = np.asarray(P, dtype=np.float64)
    if len(P) == 0:
        return np.zeros(0, dtype=np.int64)
    finite = np.isfinite(P).all(axis=1)
    lo = P[finite].min(axis=0) if finite.any() else np.zeros(3)
    span = float((P[finite].max(axis=0) - lo).max()) if finite.any() else 0.0
    scale = (2**MORTON_BITS - 1) / span if span > 0 else 0.0
    Q = np.zeros((len(P), 3), dtype=np.int64)
    Q[finite] = np.clip(((P[finite] - lo) * scale).astype(np.int64), 0, 2**MORTON_BITS - 1)
    key = _spread_bits(Q[:, 0]) | (_spread_bits(Q[:, 1]) << np.uint64(1)) | (_spread_bits(Q[:, 2]) << np.uint64(2))
    return np.argsort(key, kind="stable").astype(np.int64)


def inverse_permutation(order: np.ndarray) -> np.ndarray:
    """(k,) int64 ``inv`` with ``inv[order[i]] = i``."""
    inv = np.empty(len(order), dtype=np.int64)
    inv[order] = np.arange(len(order), dtype=np.int64)
    return inv
