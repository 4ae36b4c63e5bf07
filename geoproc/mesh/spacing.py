"""Point spacing of a cloud that may hold near copies of its points."""

from __future__ import annotations

import numpy as np

COPY_DISTANCE = 1e-4
"""Neighbours closer than this fraction of the typical distance to a point's
farthest listed neighbour count as copies of it (:func:`point_spacing`)."""


def nearest_distinct_distances(dist: np.ndarray) -> np.ndarray:
    """(n,) each point's distance to its nearest neighbour that is not a copy.

    ``dist`` (n, k) holds each point's distances to its k nearest points in
    increasing order, itself first (``cKDTree.query``). A neighbour closer than
    ``COPY_DISTANCE`` times the median of the last column counts as a copy: a
    cloud stored twice, once rounded to float32, would otherwise measure the
    rounding. A point whose every listed neighbour is a copy takes its farthest
    one; all points at one place give zeros.
    """
    far = float(np.median(dist[:, -1]))
    if not far > 0:
        return np.zeros(len(dist))
    apart = dist[:, 1:] > COPY_DISTANCE * far
    first = np.where(apart.any(axis=1), apart.argmax(axis=1), dist.shape[1] - 2)
    return dist[np.arange(len(dist)), 1 + first]


def point_spacing(dist: np.ndarray) -> float:
    """The median point spacing: the median over the points of
    :func:`nearest_distinct_distances` (``dist`` as there), or 1 when all
    points are at one place. A cloud stored twice, once rounded to float32,
    had taken the spacing down to the rounding and flagged every point as an
    outlier (and a moving cloud stored twice had fallen back to a spacing of 1
    length unit and flagged none)."""
    if not float(np.median(dist[:, -1])) > 0:
        return 1.0
    return float(np.median(nearest_distinct_distances(dist)))


def near_copy_groups(idx: np.ndarray, dist: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Points linked by chains of neighbour pairs closer than ``radius`` form a group.

    Parameters
    ----------
    idx, dist : (n, k) each point's k nearest points (itself first) and their
        distances, as ``cKDTree.query`` gives them.
    radius : float, length units.

    Returns
    -------
    (g,) the index of each group's first point, increasing, and (n,) each
    point's group (a position in the first array).

    Only the listed neighbours are linked, so the graph has at most n k edges:
    all pairs within ``radius`` (``cKDTree.query_pairs``) grow as the square of
    a clump's size, and a clump of 20,000 near copies in a million points took
    11.4 GB. A clump of more than k points can then split into a few groups,
    which are still near copies scored apart, as before this merging.
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    n = len(idx)
    i, j = np.nonzero(dist <= radius)
    graph = sp.coo_matrix((np.ones(len(i)), (i, idx[i, j])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    first = np.full(count, n)
    np.minimum.at(first, label, np.arange(n))
    keep = np.sort(first)
    return keep, np.searchsorted(keep, first[label])
