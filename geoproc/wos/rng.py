"""Counter-based per-point random streams (SplitMix64).

Every grid point ``i`` owns the stream seeded by ``(seed, i)``, so estimates do
not depend on how points are spread over threads: same seed, same numbers.
"""

from __future__ import annotations

import numba
import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0


@numba.njit(cache=True, nogil=True, inline="always")
def mix64(z):
    """SplitMix64 finalizer of a uint64."""
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@numba.njit(cache=True, nogil=True)
def stream_state(seed, index):
    """Initial uint64 state of the stream for ``(seed, index)`` (both non-negative ints)."""
    return mix64(mix64(np.uint64(seed) + _GOLDEN) ^ (np.uint64(index) * _GOLDEN + np.uint64(1)))


@numba.njit(cache=True, nogil=True, inline="always")
def next_uniform(state):
    """Advance ``state``; return ``(new_state, u)`` with u uniform in [0, 1)."""
    state = state + _GOLDEN
    return state, (mix64(state) >> _S11) * _INV53
