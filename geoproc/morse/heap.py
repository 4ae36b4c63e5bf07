"""A binary min-heap of (int64 key, int64 item) on preallocated arrays, for numba
code (the priority queues of ProcessLowerStars)."""

from __future__ import annotations

import numba


@numba.njit(cache=True, inline="always")
def heap_push(keys, items, size, key, item):
    """Insert (key, item); returns the new size."""
    i = size
    keys[i] = key
    items[i] = item
    while i > 0:
        p = (i - 1) >> 1
        if keys[p] <= keys[i]:
            break
        keys[p], keys[i] = keys[i], keys[p]
        items[p], items[i] = items[i], items[p]
        i = p
    return size + 1


@numba.njit(cache=True, inline="always")
def heap_pop(keys, items, size):
    """Remove the smallest key; returns (item, new size). ``size`` must be > 0."""
    item = items[0]
    size -= 1
    keys[0] = keys[size]
    items[0] = items[size]
    i = 0
    while True:
        c = 2 * i + 1
        if c >= size:
            break
        if c + 1 < size and keys[c + 1] < keys[c]:
            c += 1
        if keys[i] <= keys[c]:
            break
        keys[c], keys[i] = keys[i], keys[c]
        items[c], items[i] = items[i], items[c]
        i = c
    return item, size
