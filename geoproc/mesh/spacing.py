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
