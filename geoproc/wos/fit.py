"""Control-variate fit: kernel placement, fit points, ridge least squares.

The fit pass estimates u by plain walks at N points spread evenly in the
domain (farthest-point sampling) and solves the ridge problem

    min_s ||Phi_n s + b - u_hat||^2 + alpha ||s||^2,

where ``Phi_n`` holds the kernels at the fit points scaled to unit RMS per
column and ``b`` is an unpenalized constant. The coefficients returned are
``sigma = s / scale`` (the constant cancels in the estimator).
"""

from __future__ import annotations

import numba
import numpy as np

from geoproc.wos.domain import Domain
from geoproc.wos.kernels import ANGLE, GREEN, KernelSet, kernel_matrix


def boundary_samples(domain: Domain, m: int) -> tuple[np.ndarray, np.ndarray]:
    """``m`` points spread evenly by arc length over the boundary and their outward normals.

    Returns
    -------
    P, N : (m, 2) float64
    """
    E = domain.B - domain.A
    length = np.linalg.norm(E, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(length)])
    s = (np.arange(m) + 0.5) * cum[-1] / m
    seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(length) - 1)
    t = (s - cum[seg]) / length[seg]
    P = domain.A[seg] + t[:, None] * E[seg]
    N = np.stack([E[seg, 1], -E[seg, 0]], axis=1) / length[seg, None]
    return P, N


def green_centers(domain: Domain, m: int, distance_of) -> np.ndarray:
    """Centers for ``m`` Green kernels: boundary samples pushed outward by the sample spacing.

    A center must land outside the domain, at least half its offset away from
    the boundary; otherwise the offset is halved (three times), then the center
    is dropped.

    Parameters
    ----------
    distance_of : callable
        ``distance_of(P) -> (n,)`` distance to the boundary.

    Returns
    -------
    (k, 2) float64, k <= m
    """
    P, N = boundary_samples(domain, m)
    delta = np.full(m, domain.perimeter / m)
    C = P + delta[:, None] * N
    ok = np.zeros(m, dtype=bool)
    for _ in range(4):
        todo = ~ok
        C[todo] = P[todo] + delta[todo, None] * N[todo]
        good = ~domain.contains(C) & (distance_of(C) >= 0.5 * delta)
        ok |= good & todo
        delta[~ok] *= 0.5
        if ok.all():
            break
    return C[ok]


def green_kernels(domain: Domain, m: int, distance_of) -> KernelSet:
    """:class:`KernelSet` of Green kernels centered outside the domain."""
    C = np.ascontiguousarray(green_centers(domain, m, distance_of))
    return KernelSet(GREEN, C, C.copy(), np.arange(len(C), dtype=np.int64), len(C))


def angle_kernels(domain: Domain, m: int) -> KernelSet:
    """:class:`KernelSet` of ``m`` angle kernels, each an arc of consecutive boundary segments.

    Each loop gets a share of the ``m`` arcs proportional to its length (at least
    one); a loop's segments are split into arcs of nearly equal segment count.
    With fewer segments than ``m``, every segment is its own kernel.
    """
    S = domain.n_segments
    length = np.linalg.norm(domain.B - domain.A, axis=1)
    col = np.empty(S, dtype=np.int64)
    total = length.sum()
    nloops = int(domain.loop_of.max()) + 1
    nxt = 0
    for lp in range(nloops):
        idx = np.flatnonzero(domain.loop_of == lp)
        k = int(np.clip(round(m * length[idx].sum() / total), 1, len(idx)))
        if S <= m:
            k = len(idx)
        col[idx] = nxt + (np.arange(len(idx)) * k) // len(idx)
        nxt += k
    return KernelSet(ANGLE, np.ascontiguousarray(domain.A), np.ascontiguousarray(domain.B), col, nxt)


def spread_points(candidates: np.ndarray, n: int, start: int = 0) -> np.ndarray:
    """Farthest-point sampling of ``n`` indices among ``candidates`` (k, 2) (deterministic).

    Compiled, one pass over the candidates per point chosen (numpy's array
    passes had taken 50 of cv-green's 56 s at ``--grid 2048``); the same
    indices as those passes give (the same squared distances, the first
    farthest)."""
    k = len(candidates)
    if k <= n:
        return np.arange(k)
    return _farthest_points(np.ascontiguousarray(candidates, dtype=np.float64), int(n), int(start))


@numba.njit(cache=True, nogil=True)
def _farthest_points(C, n, start):
    k = C.shape[0]
    chosen = np.empty(n, dtype=np.int64)
    chosen[0] = start
    d = np.empty(k)
    for j in range(k):
        dx, dy = C[j, 0] - C[start, 0], C[j, 1] - C[start, 1]
        d[j] = dx * dx + dy * dy
    for i in range(1, n):
        best, at = -1.0, 0
        for j in range(k):  # the first largest, as np.argmax
            if d[j] > best:
                best, at = d[j], j
        chosen[i] = at
        x, y = C[at, 0], C[at, 1]
        for j in range(k):
            dx, dy = C[j, 0] - x, C[j, 1] - y
            e = dx * dx + dy * dy
            if e < d[j]:
                d[j] = e
    return chosen


FLAT_SPREAD = 1e-9
"""A fit column whose standard deviation is at most this times the largest
magnitude of any column is taken as constant (its spread is rounding: a hole's
whole-loop angle kernel is 0 ± 1e-16 outside the hole)."""


def ridge_fit(Phi: np.ndarray, u: np.ndarray, alpha: float, dPhi: np.ndarray | None = None,
              flux: np.ndarray | None = None) -> tuple[np.ndarray, float, np.ndarray]:
    """Ridge least squares on columns scaled to unit standard deviation, with a
    free (unpenalized) constant.

    The constant absorbs each column's mean, so only the spread of a column
    sets its penalty: a Green kernel ``-log|x - y| / 2 pi`` gains the constant
    ``-log s / 2 pi`` when the domain is measured in another unit (scaled by
    s), which changes its RMS but not its spread, and the fit stays the same.

    Parameters
    ----------
    Phi : (N, M) float64
        Kernels at the fit points.
    u : (N,) float64
        Estimates of u there.
    alpha : float
        Ridge weight (on the coefficients of the scaled columns).
    dPhi : (K, M) float64, optional
        Extra rows: kernels' (weighted) normal derivatives at Neumann boundary samples.
    flux : (K,) float64, optional
        Their targets: the (equally weighted) Neumann data there.

    Returns
    -------
    sigma : (M,) float64
        Coefficients of the unscaled kernels.
    b : float
        Constant term.
    scale : (M,) float64
        Column standard deviations used (1 for a constant column).

    A column whose spread is within rounding of its size (:data:`FLAT_SPREAD`)
    is constant over the fit points, as an angle kernel over a whole closed
    loop is (2 pi or 0 inside the domain): the free constant stands for it and
    its coefficient is 0, unless Neumann rows set it (with one fit point every
    column is flat, and those rows alone determine the fit). Scaled by its
    rounding noise it had taken a coefficient near 1e14, and the control
    variate, added back, cancelled catastrophically (a star with one kernel:
    rmse 2.9 against 0.046 without it, its error bars blind to the rounding).
    """
    mean = Phi.mean(axis=0)
    scale = Phi.std(axis=0)
    size = float(np.abs(Phi).max()) if Phi.size else 0.0  # the kernels' scale: their rounding is relative to it
    flat = ~(scale > FLAT_SPREAD * size)  # also a spread of exactly 0, or NaN
    scale[flat] = 1.0
    M = Phi.shape[1]
    cols = (Phi - mean) / scale
    cols[:, flat] = 0.0
    D = np.hstack([cols, np.ones((len(Phi), 1))])  # centred: the constant takes the means
    y = np.asarray(u, dtype=np.float64)
    neumann = dPhi is not None and len(dPhi) > 0
    if neumann:  # a flat column's normal derivatives still set its coefficient (scale 1 there)
        D = np.vstack([D, np.hstack([dPhi / scale, np.zeros((len(dPhi), 1))])])
        y = np.concatenate([y, flux])
    pen = np.full(M + 1, float(alpha))
    pen[-1] = 0.0
    if alpha > 0:
        x = np.linalg.solve(D.T @ D + np.diag(pen), D.T @ y)
    else:  # no ridge: least squares, the minimum-norm fit (centred, scaled columns) when rows do not determine it
        x = np.linalg.lstsq(D, y, rcond=None)[0]
    sigma = x[:M] / scale
    if not neumann:
        sigma[flat] = 0.0
    return sigma, float(x[M] - sigma @ mean), scale


def neumann_samples(domain: Domain, m: int) -> tuple[np.ndarray, np.ndarray]:
    """About ``m`` points spread by arc length over the Neumann segments, with outward normals."""
    P, N, _ = neumann_samples_and_ends(domain, m)
    return P, N


def neumann_samples_and_ends(domain: Domain, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`neumann_samples` (m, 2), (m, 2), and each point's distance to the
    nearer end of its segment (m,), in length units."""
    sel = np.flatnonzero(domain.neumann)
    E = domain.B[sel] - domain.A[sel]
    length = np.linalg.norm(E, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(length)])
    s = (np.arange(m) + 0.5) * cum[-1] / m
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(length) - 1)
    t = (s - cum[k]) / length[k]
    P = domain.A[sel[k]] + t[:, None] * E[k]
    N = domain.outward_normals[sel[k]]
    return P, N, np.minimum(t, 1 - t) * length[k]


def fit_control_variate(Phi: np.ndarray, u: np.ndarray, alpha: float) -> np.ndarray:
    """Coefficients ``sigma`` (M,) of the ridge fit (see :func:`ridge_fit`)."""
    return ridge_fit(Phi, u, alpha)[0]


def make_kernels(method: str, domain: Domain, m: int, distance_of) -> KernelSet:
    """Kernel family for a method: Green for cv-green and npass, angle for cv-angle."""
    if method == "cv-angle":
        return angle_kernels(domain, m)
    return green_kernels(domain, m, distance_of)


def fit_points(candidates: np.ndarray, n: int) -> np.ndarray:
    """``n`` points (n, 2) spread evenly among interior candidates (k, 2)."""
    return candidates[spread_points(candidates, n)]


__all__ = ["angle_kernels", "boundary_samples", "fit_control_variate", "fit_points",
           "green_centers", "green_kernels", "kernel_matrix", "make_kernels", "ridge_fit",
           "spread_points"]
