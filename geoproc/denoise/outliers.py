"""Outlier removal in point clouds by RPCA on neighbourhood matrices.

For every point, the (k, 3) matrix of its k nearest neighbours, centred on their
coordinate-wise median, is split by RPCA into ``P + S``: on a smooth surface the
centred neighbourhood is (nearly) rank two, so points off the surface show up as
large rows of the sparse part S (Eq. 21-28 of the review). Every point lies in
many neighbourhoods; the refinement merges its overlapping local estimates
(Eq. 29-30): its score is the mean of its sparse residuals over every
neighbourhood it belongs to, and its refined position is the mean of its
low-rank estimates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from geoproc.denoise.rpca import rpca
from geoproc.errors import InputError


@dataclass
class OutlierResult:
    """Output of :func:`rpca_outliers`.

    Attributes
    ----------
    score : (n,) float64
        Merged sparse residual of each point, in units of the median point spacing.
    outlier : (n,) bool
        ``score > threshold``.
    threshold : float
        The cut used.
    refined : (n, 3) float64
        Merged low-rank position estimates (the refinement).
    """

    score: np.ndarray
    outlier: np.ndarray
    threshold: float
    refined: np.ndarray


def otsu_threshold(x: np.ndarray, bins: int = 256) -> float:
    """Otsu's threshold: the cut maximising the between-class variance of a histogram."""
    hist, edges = np.histogram(x, bins=bins)
    mids = 0.5 * (edges[1:] + edges[:-1])
    w0 = np.cumsum(hist)
    w1 = w0[-1] - w0
    s0 = np.cumsum(hist * mids)
    m0 = s0 / np.maximum(w0, 1)
    m1 = (s0[-1] - s0) / np.maximum(w1, 1)
    between = w0 * w1 * (m0 - m1) ** 2
    return float(mids[int(np.argmax(between[:-1]))])


def _group_median(vals: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Median of each consecutive group ``vals[starts[j]:starts[j + 1]]``."""
    n = len(starts) - 1
    out = np.zeros(n)
    sizes = np.diff(starts)
    for size in np.unique(sizes):
        if size == 0:
            continue
        groups = np.flatnonzero(sizes == size)
        block = vals[starts[groups][:, None] + np.arange(size)[None, :]]
        out[groups] = np.median(block, axis=1)
    return out


def robust_planes(D: np.ndarray, lam: float | None = None) -> np.ndarray:
    """(b, 3) unit normal of the plane through each centred (b, k, 3) neighbourhood:
    the least singular direction of the RPCA low-rank part (outlying rows go to
    the sparse part and do not tilt the plane)."""
    res = rpca(D, lam=lam, tol=1e-7, max_iter=300)
    _, _, Wt = np.linalg.svd(res.P, full_matrices=False)
    return Wt[:, -1, :]


def _plane_residual_to_inliers(P, inlier, k, lam, spacing):
    """Distance of every point to the robust plane of its k nearest current inliers
    (itself excluded), in spacings."""
    keep = np.flatnonzero(inlier)
    tree = cKDTree(P[keep])
    _, j = tree.query(P, k=k + 1)
    own = keep[j] == np.arange(len(P))[:, None]
    # drop the point itself where it is among its inlier neighbours, else the farthest
    drop = np.where(own.any(axis=1), own.argmax(axis=1), k)
    mask = np.ones_like(j, dtype=bool)
    mask[np.arange(len(P)), drop] = False
    nbr = keep[j[mask].reshape(len(P), k)]
    nb = P[nbr]
    center = np.median(nb, axis=1)
    normal = robust_planes((nb - center[:, None, :]) / spacing, lam)
    return np.abs(np.einsum("nc,nc->n", P - center, normal)) / spacing


def rpca_outliers(P: np.ndarray, k: int = 16, threshold: float | None = None,
                  path: str | None = None, lam: float | None = 0.5,
                  refine_passes: int = 0) -> OutlierResult:
    """Score and flag outliers of a point cloud.

    Parameters
    ----------
    P : (n, 3) float64 points.
    k : int
        Neighbourhood size (the point itself included).
    threshold : float, optional
        Cut on the score, in median point spacings (default 0.5).
    lam : float, optional
        RPCA sparsity weight (None: ``1/sqrt(k)``); 0.5 keeps the low-rank part
        of a (k, 3) neighbourhood close to its plane.
    refine_passes : int
        Passes that re-fit every point's plane from its k nearest current
        inliers and re-score it (the refinement).
    path : str, optional
        File name for errors.

    Returns
    -------
    OutlierResult
    """
    n = len(P)
    if k < 4:
        raise InputError(path, f"--k {k}: neighbourhoods need at least 4 points")
    if n < k:
        raise InputError(path, f"has {n} points, fewer than the neighbourhood size k={k}")
    tree = cKDTree(P)
    dist, idx = tree.query(P, k=k)
    spacing = float(np.median(dist[:, 1]))
    if spacing <= 0:
        spacing = float(dist[:, 1][dist[:, 1] > 0].mean()) if (dist[:, 1] > 0).any() else 1.0
    nb = P[idx]
    center = np.median(nb, axis=1, keepdims=True)
    D = (nb - center) / spacing
    res = rpca(D, lam=lam, tol=1e-7, max_iter=300)
    # robust plane of every neighbourhood: the least singular direction of P
    _, _, Wt = np.linalg.svd(res.P, full_matrices=False)
    normal = Wt[:, -1, :]  # (n, 3)
    resid = np.abs(np.einsum("nkc,nc->nk", D, normal))  # (n, k) off-plane distances
    flat = idx.reshape(-1)
    count = np.bincount(flat, minlength=n).astype(np.float64)
    order = np.argsort(flat, kind="stable")
    starts = np.concatenate([[0], np.cumsum(count.astype(np.int64))])
    vals = resid.reshape(-1)[order]
    score = np.array([np.median(vals[starts[j]:starts[j + 1]]) for j in range(n)]) if n < 0 else \
        _group_median(vals, starts)
    est = res.P * spacing + center
    refined = np.column_stack([np.bincount(flat, weights=est[:, :, c].reshape(-1), minlength=n)
                               for c in range(3)]) / count[:, None]
    if threshold is None:
        threshold = 0.5
    outlier = score > threshold
    if refine_passes and (~outlier).sum() >= k:
        for _ in range(refine_passes):
            score = _plane_residual_to_inliers(P, ~outlier, k, lam, spacing)
            outlier = score > threshold
    return OutlierResult(score=score, outlier=outlier, threshold=float(threshold), refined=refined)


def detection_scores(predicted: np.ndarray, truth: np.ndarray) -> dict:
    """Precision, recall and F1 of a boolean detection against the truth."""
    predicted = np.asarray(predicted, dtype=bool)
    truth = np.asarray(truth, dtype=bool)
    tp = float((predicted & truth).sum())
    precision = tp / max(float(predicted.sum()), 1.0)
    recall = tp / max(float(truth.sum()), 1.0)
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return {"precision": precision, "recall": recall, "f1": f1}
