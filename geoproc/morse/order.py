"""The total order on vertices every Morse computation uses."""

from __future__ import annotations

import numpy as np


def vertex_order(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sort vertices by (value, vertex index).

    Parameters
    ----------
    f : (n,) float array
        Vertex values (finite).

    Returns
    -------
    order : (n,) int64 array
        Vertex indices from lowest to highest.
    rank : (n,) int64 array
        Position of each vertex in ``order`` (``rank[order] = arange(n)``); the
        injective function every algorithm in :mod:`geoproc.morse` compares.
    """
    f = np.asarray(f, dtype=np.float64)
    order = np.argsort(f, kind="stable").astype(np.int64)  # stable: ties by index
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order), dtype=np.int64)
    return order, rank
