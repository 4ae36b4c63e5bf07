"""Outlier removal in point clouds by RPCA on neighbourhood matrices.

For every point, the (k, 3) matrix of its k nearest neighbours, centred on their
coordinate-wise median, is split by RPCA into ``P + S``: on a smooth surface the
centred neighbourhood is (nearly) rank two, so points off the surface show up as
large rows of the sparse part S (Eq. 21-28 of the review). Every point lies in
many neighbourhoods; the refinement merges its overlapping local estimates
(Eq. 29-30): its score is the median of its distances to the robust planes of
every neighbourhood it belongs to, and its refined position is the mean of its
projections onto the planes of the inlier-centred neighbourhoods that contain
it (the minimiser of the summed squared distances to those local estimates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from geoproc.denoise.rpca import rpca
from geoproc.errors import InputError
from geoproc.mesh.clean import unique_rows
from geoproc.mesh.spacing import COPY_DISTANCE, near_copy_groups, point_spacing
from geoproc.mesh.validate import mesh_arrays


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
        Refined positions: the mean of the point's projections onto the robust
        planes of the neighbourhoods (centred on inliers) that contain it; the
        input position where there is none.
    """

    score: np.ndarray
    outlier: np.ndarray
    threshold: float
    refined: np.ndarray


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


def robust_frames(nb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(b, 3) origin and (b, 3, 3) axes (columns) of a frame for each (b, k, 3)
    neighbourhood that turns with it: the mean and the principal axes (the
    covariance's eigenvectors) of the half of its points nearest its mean.
    The half keeps a few far outliers from tilting the axes: with all points,
    one point 3 half-widths off a 16-point square patch tilted the robust
    plane by 23°, with the near half by none."""
    k = nb.shape[1]
    d = np.linalg.norm(nb - nb.mean(axis=1, keepdims=True), axis=2)
    near = np.argsort(d, axis=1, kind="stable")[:, : (k + 1) // 2]
    sub = np.take_along_axis(nb, near[..., None], axis=1)
    mean = sub.mean(axis=1)
    X = sub - mean[:, None, :]
    _, R = np.linalg.eigh(np.einsum("bki,bkj->bij", X, X))
    return mean, R


def robust_planes(nb: np.ndarray, spacing: float = 1.0,
                  lam: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The robust plane of each (b, k, 3) neighbourhood ``nb``: (b, 3) a point
    on it and (b, 3) its unit normal.

    Each neighbourhood is expressed in a frame of its own (:func:`robust_frames`)
    and centred on its coordinate-wise median there, in units of ``spacing``;
    RPCA splits it into a low-rank part and sparse outlying entries, and the
    normal is the low-rank part's least singular direction (outlying rows go
    to the sparse part and do not tilt the plane). RPCA's sparse term is
    entrywise, so in world axes its result did not turn with the input: a
    fandisk cloud under a generic rotation changed 133 of its flags. The frame turns
    with the points, and the entrywise term does not see the signs or the
    order of its axes, so the planes now turn with the input."""
    center = np.empty((len(nb), 3))
    normal = np.empty((len(nb), 3))
    for lo in range(0, len(nb), _PLANE_BLOCK):
        block = slice(lo, lo + _PLANE_BLOCK)
        center[block], normal[block] = _robust_planes_block(nb[block], spacing, lam)
    return center, normal


# Neighbourhoods solved together: each is independent, so the result does not
# depend on this; it bounds the temporaries (about 4 KB per neighbourhood of 16).
_PLANE_BLOCK = 32768


def _robust_planes_block(nb, spacing, lam):
    """:func:`robust_planes` on one block of neighbourhoods."""
    mean, R = robust_frames(nb)
    X = nb - mean[:, None, :]
    local = np.einsum("bkc,bcd->bkd", X, R)
    med = np.median(local, axis=1)
    res = rpca((local - med[:, None, :]) / spacing, lam=lam, tol=1e-7, max_iter=300)
    _, _, Wt = np.linalg.svd(res.P, full_matrices=False)
    normal = np.einsum("bcd,bd->bc", R, Wt[:, -1, :])
    return mean + np.einsum("bcd,bd->bc", R, med), normal


def _plane_residual_to_inliers(P, inlier, k, lam, spacing):
    """Distance of every point to the robust plane of its k nearest current inliers
    (itself excluded), in spacings."""
    keep = np.flatnonzero(inlier)
    tree = cKDTree(P[keep])
    _, j = tree.query(P, k=k + 1, workers=-1)
    own = keep[j] == np.arange(len(P))[:, None]
    # drop the point itself where it is among its inlier neighbours, else the farthest
    drop = np.where(own.any(axis=1), own.argmax(axis=1), k)
    mask = np.ones_like(j, dtype=bool)
    mask[np.arange(len(P)), drop] = False
    nbr = keep[j[mask].reshape(len(P), k)]
    center, normal = robust_planes(P[nbr], spacing, lam)
    return np.abs(np.einsum("nc,nc->n", P - center, normal)) / spacing


def default_outlier_threshold(score: np.ndarray) -> float:
    """The default cut on outlier scores (in point spacings): ``max(0.5, 3
    median(score))``. The median follows the typical score of the inliers:
    near 0 on a dense cloud without noise, where the cut is half a spacing,
    and higher with noise (about 0.2 spacings at Gaussian noise of 0.3 along
    the normals), so that the noise's tail is not flagged; but also higher on
    a sparse cloud, whose curvature between points scores as noise, and with
    many outliers. ``bench/denoise_outlier_threshold.py`` compares it with the
    fixed cut 0.5: better or equal on 20,000- and 100,000-point clouds,
    worse on clouds of a mesh's few thousand vertices with 20 % outliers."""
    return max(0.5, 3.0 * float(np.median(score))) if np.size(score) else 0.5


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
        Cut on the score, in median point spacings; default
        :func:`default_outlier_threshold` of the scores.
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

    Coincident points (a scan stored twice, merged scans) are scored once and
    share the result: kept as they are, every point of a cloud stored twice
    had a copy at spacing 0, and nothing was flagged (F1 0 on the torus
    fixture, 0.88 once). The distinct points are scored in lexicographic
    order, so that the result does not depend on the order of the input: the
    k-d tree returns equidistant neighbours in its own order, and on a
    regularly sampled torus, with the points shuffled, that moved scores by up
    to 0.4 of their range.
    """
    if k < 4:
        raise InputError(path, f"--k {k}: neighbourhoods need at least 4 points")
    P, _ = mesh_arrays(P, np.zeros((0, 3), dtype=np.int64), path, allow_point_cloud=True)
    U, inv = unique_rows(P)
    if len(U) < k:
        raise InputError(path, f"has {len(U)} distinct point{'s' if len(U) != 1 else ''}, fewer than the "
                               f"neighbourhood size k={k}")
    res = _score_distinct_points(U, k, threshold, path, lam, refine_passes)
    return OutlierResult(score=res.score[inv], outlier=res.outlier[inv], threshold=res.threshold,
                         refined=res.refined[inv])


def _score_distinct_points(P, k, threshold, path, lam, refine_passes, merged=False) -> OutlierResult:
    """:func:`rpca_outliers` on points that are pairwise distinct. Near copies
    (closer than ``COPY_DISTANCE`` of the typical distance to the k-th
    neighbour: a cloud stored twice, once rounded to float32) are scored once,
    as exact copies are: kept apart, they halved every neighbourhood's extent
    and the torus fixture stored so scored F1 0.78 instead of 0.90."""
    n = len(P)
    if n < k:
        # (reached only with near copies merged: rpca_outliers checked the distinct points)
        raise InputError(path, f"has {n} points once near copies are merged, fewer than the neighbourhood "
                               f"size k={k}")
    tree = cKDTree(P)
    dist, idx = tree.query(P, k=k, workers=-1)
    far = float(np.median(dist[:, -1]))
    if not merged and far > 0 and (dist[:, 1] <= COPY_DISTANCE * far).any():
        keep, group = near_copy_groups(idx, dist, COPY_DISTANCE * far)
        res = _score_distinct_points(P[keep], k, threshold, path, lam, refine_passes, merged=True)
        return OutlierResult(score=res.score[group], outlier=res.outlier[group], threshold=res.threshold,
                             refined=res.refined[group])
    spacing = point_spacing(dist)
    del dist
    nb = P[idx]
    center, normal = robust_planes(nb, spacing, lam)
    score = median_plane_distance(nb, idx, center, normal, n, spacing)
    if threshold is None:
        threshold = default_outlier_threshold(score)
    outlier = score > threshold
    if refine_passes and (~outlier).sum() >= k:
        for _ in range(refine_passes):
            score = _plane_residual_to_inliers(P, ~outlier, k, lam, spacing)
            outlier = score > threshold
    refined = merged_projections(nb, idx, normal, center, ~outlier, P)
    return OutlierResult(score=score, outlier=outlier, threshold=float(threshold), refined=refined)


def median_plane_distance(nb: np.ndarray, idx: np.ndarray, center: np.ndarray, normal: np.ndarray,
                          n: int, unit: float = 1.0) -> np.ndarray:
    """(n,) median, over the neighbourhoods that hold each point, of the point's
    distance to their planes, in units of ``unit`` (a length in the units of ``nb``).

    Neighbourhood j holds the points ``idx[j]`` (b, k) at ``nb[j]`` (b, k, 3);
    its plane passes through ``center[j]`` with unit ``normal[j]`` (b, 3). Every
    point is in at least its own neighbourhood."""
    resid = np.abs(np.einsum("nkc,nc->nk", nb - center[:, None, :], normal)) / unit  # (b, k) off-plane
    flat = idx.reshape(-1)
    order = np.argsort(flat, kind="stable")
    starts = np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=n))])
    return _group_median(resid.reshape(-1)[order], starts)


def merged_projections(nb: np.ndarray, idx: np.ndarray, normal: np.ndarray, center: np.ndarray,
                       use: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Merge the overlapping local estimates of every point (Eq. 29-30).

    Neighbourhood j (its members ``idx[j]`` at ``nb[j]``, robust plane through
    ``center[j]`` with unit ``normal[j]``) estimates each member by its
    projection onto the plane. The point's refined position minimises the sum of
    squared distances to its estimates from the neighbourhoods with ``use[j]``:
    their mean (the input position when no such neighbourhood contains it).

    Parameters
    ----------
    nb : (b, k, 3) member positions; idx : (b, k) member indices; normal, center : (b, 3);
    use : (b,) bool; P : (n, 3) input positions.

    Returns
    -------
    (n, 3) float64
    """
    n = len(P)
    rows = np.flatnonzero(use)
    count = np.bincount(idx[rows].reshape(-1), minlength=n).astype(np.float64)
    total = np.zeros((n, 3))
    # block by block, each added in neighbourhood order (as one bincount would)
    for lo in range(0, len(rows), _PLANE_BLOCK):
        r = rows[lo:lo + _PLANE_BLOCK]
        members = nb[r]
        off = np.einsum("bkc,bc->bk", members - center[r, None, :], normal[r])
        proj = members - off[..., None] * normal[r, None, :]
        flat = idx[r].reshape(-1)
        for c in range(3):
            np.add.at(total[:, c], flat, proj[:, :, c].reshape(-1))
    return np.where(count[:, None] > 0, total / np.maximum(count, 1.0)[:, None], P)


def detection_scores(predicted: np.ndarray, truth: np.ndarray) -> dict:
    """Precision, recall and F1 of a boolean detection against the truth.

    Returns
    -------
    dict with ``precision`` (NaN when nothing is detected), ``recall`` (NaN
    when the truth holds no outlier) and ``f1 = 2 tp / (2 tp + fp + fn)``
    (NaN when both are empty).
    """
    predicted = np.asarray(predicted, dtype=bool)
    truth = np.asarray(truth, dtype=bool)
    tp = float((predicted & truth).sum())
    n_pred, n_true = float(predicted.sum()), float(truth.sum())
    precision = tp / n_pred if n_pred else float("nan")
    recall = tp / n_true if n_true else float("nan")
    f1 = 2 * tp / (n_pred + n_true) if n_pred + n_true else float("nan")
    return {"precision": precision, "recall": recall, "f1": f1}


@dataclass
class AnimationOutlierResult:
    """Output of :func:`rpca_animation_outliers`.

    Attributes
    ----------
    score : (T, n) float64
        Distance of each point in each frame from its robust low-rank trajectory,
        in point spacings (:func:`frames_spacing`: the median over the frames).
    outlier : (T, n) bool
        ``score > threshold``.
    threshold : float
        The cut used (spacings).
    refined : (T, n, 3) float64
        The low-rank trajectories (coherent motion: outliers pulled back, noise reduced).
    rank : int
        Dimension of the motion basis: the rank of the RPCA low-rank part, plus
        the constant part (the column medians).
    rpca_iterations : int
    """

    score: np.ndarray
    outlier: np.ndarray
    threshold: float
    refined: np.ndarray
    rank: int
    rpca_iterations: int


def _robust_trajectory_fit(X: np.ndarray, B: np.ndarray, w: np.ndarray, c: float,
                           iterations: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Fit every point's trajectory in the motion basis by iteratively reweighted
    least squares (Cauchy weights ``1 / (1 + (r / c)^2)`` on the per-frame residual).

    X : (n, T, 3) trajectories; B : (T, 3, r) orthonormal basis of trajectories
    (a row of the animation matrix is ``C_p B``); w : (n, T) initial weights.
    Returns the fitted (n, T, 3) trajectories and the (n, T) residual norms.

    The products are einsum's own loops, not BLAS: OpenBLAS's ``w @ outer``
    gave other last bits with two threads than with one (12 elephant frames,
    6,034 points: 499 refined coordinates moved by up to 9e-14).
    """
    r = B.shape[2]
    outer = np.einsum("tcr,tcs->trs", B, B).reshape(len(B), r * r)  # (T, r*r)
    fit = X
    res = np.zeros(X.shape[:2])
    for _ in range(iterations):
        G = np.einsum("nt,tk->nk", w, outer).reshape(-1, r, r) + 1e-12 * np.eye(r)
        rhs = np.einsum("ntc,tcr->nr", w[:, :, None] * X, B)  # (n, r)
        C = np.linalg.solve(G, rhs[:, :, None])[:, :, 0]
        fit = np.einsum("nr,tcr->ntc", C, B)  # (n, T, 3)
        res = np.linalg.norm(X - fit, axis=2)
        w = 1.0 / (1.0 + (res / c) ** 2)
    return fit, res


def _right_singular_pairs(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values (q,), largest first, and right singular vectors (q, q)
    as columns of a tall (p, q) matrix, from the eigenvectors of its Gram
    matrix ``P^T P``. ``np.linalg.svd`` of the (points, 3 frames) matrix gave
    other last bits with another number of BLAS threads (1.8e-12 in the
    singular values of the moving-cloud fixture), and every score with them;
    only values above 1e-3 of the largest are used, far above what squaring
    loses (1e-8 of it)."""
    w, W = np.linalg.eigh(P.T @ P)
    order = np.argsort(w)[::-1]
    return np.sqrt(np.maximum(w[order], 0.0)), W[:, order]


def frames_spacing(V: np.ndarray) -> float | None:
    """The point spacing of a moving cloud V (T, n, 3): the median over its
    frames of each frame's :func:`~geoproc.mesh.spacing.point_spacing`,
    leaving out frames where most points share their position with their 15
    nearest neighbours (all at one place, or a few places); None when every frame is
    so, or with fewer than 2 points (no length to score in: a spacing of 1
    length unit had been taken, which made the flags depend on the units).
    Small frames are queried on one thread: a thread pool per frame made
    20,000 frames of 4 points take 33 s instead of about 2."""
    T, n, _ = V.shape
    if n < 2:  # no neighbour to measure
        return None
    workers = -1 if n >= 20000 else 1
    spacings = []
    for Vt in V:
        dist = cKDTree(Vt).query(Vt, k=min(n, 16), workers=workers)[0]
        if float(np.median(dist[:, -1])) > 0:  # (all at one place: point_spacing's 1 is no length)
            spacings.append(point_spacing(dist))
    return float(np.median(spacings)) if spacings else None


def rpca_animation_outliers(V: np.ndarray, threshold: float | None = None, lam: float | None = None,
                            path: str | None = None) -> AnimationOutlierResult:
    """Outliers of a time-varying point cloud by RPCA on its animation matrix.

    Every point's trajectory is a row of the (n, 3T) animation matrix (its
    x, y, z in every frame), each column centred on its median. A cloud that
    moves coherently makes this matrix low-rank: a rigid or affine motion gives
    rank 4 (a row is ``[x_p, 1]`` times a 4 x 3T motion), a skinned motion with
    B bones at most 4B. A point displaced in some frames (an outlier) adds a few
    large entries: RPCA splits the matrix into ``P + S``
    (:func:`geoproc.denoise.rpca.rpca`). The right singular vectors of P span
    the motion; since the nuclear norm shrinks P, every point's trajectory is
    then refitted in that basis by reweighted least squares (the refinement,
    robust to the frames in which it is an outlier), and its score in each
    frame is its distance to the fit, in point spacings (the median over the
    frames of each frame's median spacing).

    Parameters
    ----------
    V : (T, n, 3) float64 positions per frame (same points in every frame).
    threshold : float, optional
        Cut on the score in spacings; default :func:`default_outlier_threshold`
        of the scores.
    lam : float, optional
        RPCA sparsity weight (default ``1/sqrt(max(n, 3T))``).
    path : str, optional
        File name for errors.

    Returns
    -------
    AnimationOutlierResult
    """
    from geoproc.denoise.rpca import rpca

    V = np.asarray(V, dtype=np.float64)
    T, n, _ = V.shape
    if T < 3:
        raise InputError(path, f"has {T} frames; RPCA on the animation matrix needs at least 3")
    if n < 2:
        raise InputError(path, f"has {n} points per frame; at least 2 are needed")
    # the unit and the origin from every frame alike: taken from the first frame, they
    # made the flags depend on the order of the frames (274 of 160,000 changed when the
    # frames were rolled by 7)
    spacing = frames_spacing(V)
    if spacing is None:  # (a single cloud so is refused for its few distinct points)
        raise InputError(path, f"has no frame with a point spacing: in every frame most points share their "
                         f"position with their {min(n, 16) - 1} nearest neighbours (too few distinct positions "
                         "to score outliers in)")
    origin = V.mean(axis=(0, 1))  # centred first: far from 0 the positions' own digits would be lost
    X = (V - origin).transpose(1, 0, 2) / spacing  # (n, T, 3)
    # in the principal axes of all the positions, which turn with the animation: RPCA's
    # sparse term is entrywise, so in world axes its result did not
    _, R = np.linalg.eigh(np.einsum("nti,ntj->ij", X, X))
    X = X @ R
    D = X.reshape(n, 3 * T)
    med = np.median(D, axis=0, keepdims=True)
    res = rpca(D - med, lam=lam, tol=1e-7, max_iter=500)
    s, W = _right_singular_pairs(res.P)
    rank = int((s > 1e-3 * s[0]).sum()) if len(s) and s[0] > 0 else 0
    # the basis: the column medians (a row's constant part) and the motion of P
    B, _ = np.linalg.qr(np.column_stack([med[0], W[:, :rank]]))
    B = B.reshape(T, 3, -1)
    S = np.linalg.norm(res.S.reshape(n, T, 3), axis=2)  # (n, T) sparse residual per point and frame
    fit, resid = _robust_trajectory_fit(X, B, 1.0 / (1.0 + (S / 0.5) ** 2), 0.5)
    score = resid.T
    if threshold is None:
        threshold = default_outlier_threshold(score)
    return AnimationOutlierResult(score=score, outlier=score > threshold, threshold=float(threshold),
                                  refined=(fit @ R.T).transpose(1, 0, 2) * spacing + origin, rank=B.shape[2],
                                  rpca_iterations=res.iterations)
