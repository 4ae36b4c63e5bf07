"""Union-find on an int64 parent array, for compiled (numba) loops."""

from __future__ import annotations

import numba


@numba.njit(cache=True, inline="always")
def find(parent, x):
    """Root of ``x`` in the forest ``parent`` (int64 array), halving the path on the way."""
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x
