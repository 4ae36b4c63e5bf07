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


def near_copy_groups(P: np.ndarray, k: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, 3) gathered with their near copies (:data:`COPY_DISTANCE`
    times the median distance to the k-th nearest point, chained).

    Returns
    -------
    first : (g,) int array
        One point of each group, its lowest index (all points when no two are near copies).
    group : (n,) int array
        Each point's group, an index into ``first``.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    n = len(P)
    if n < 2:
        return np.arange(n), np.arange(n)
    tree = cKDTree(P)
    dist, _ = tree.query(P, k=min(n, k), workers=-1)
    far = float(np.median(dist[:, -1]))
    pairs = tree.query_pairs(COPY_DISTANCE * far, output_type="ndarray") if far > 0 else np.zeros((0, 2), int)
    if not len(pairs):
        return np.arange(n), np.arange(n)
    _, label = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                    directed=False)
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    order = np.argsort(first)  # groups numbered by their lowest point
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return first[order], rank[label]
