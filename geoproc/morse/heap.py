"""A binary min-heap of (key, int64 item) pairs on preallocated arrays, for numba
code (the priority queues of ProcessLowerStars and the monotone sweeps of the
simplification). Pairs are ordered by key, then by item, so the pop order is
fully determined even when keys tie. Keys may be int64 or float64."""

from __future__ import annotations

import numba


@numba.njit(cache=True, inline="always")
def _before(keys, items, a, b):
    """True when entry a orders strictly before entry b: (key, item) lexicographically."""
    return keys[a] < keys[b] or (keys[a] == keys[b] and items[a] < items[b])


@numba.njit(cache=True, inline="always")
def heap_push(keys, items, size, key, item):
    """Insert (key, item); returns the new size."""
    i = size
    keys[i] = key
    items[i] = item
    while i > 0:
        p = (i - 1) >> 1
        if _before(keys, items, p, i):
            break
        keys[p], keys[i] = keys[i], keys[p]
        items[p], items[i] = items[i], items[p]
        i = p
    return size + 1


@numba.njit(cache=True, inline="always")
def heap_pop(keys, items, size):
    """Remove the smallest (key, item); returns (item, new size). ``size`` must be > 0."""
    item = items[0]
    size -= 1
    keys[0] = keys[size]
    items[0] = items[size]
    i = 0
    while True:
        c = 2 * i + 1
        if c >= size:
            break
        if c + 1 < size and _before(keys, items, c + 1, c):
            c += 1
        if _before(keys, items, i, c):
            break
        keys[c], keys[i] = keys[i], keys[c]
        items[c], items[i] = items[i], items[c]
        i = c
    return item, size
