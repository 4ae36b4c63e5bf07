"""Robust principal component analysis: ``D = P + S`` with P low-rank and S sparse,
by the inexact augmented Lagrange multiplier method (Lin, Chen and Ma 2010;
Eq. 25-28 of the review)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class RPCAResult:
    """Output of :func:`rpca`.

    Attributes
    ----------
    P : array, shape of D
        Low-rank part.
    S : array, shape of D
        Sparse part.
    iterations : int
        ALM iterations run.
    converged : bool
        Whether ``|D - P - S|_F <= tol |D|_F`` held for every matrix.
    """

    P: np.ndarray
    S: np.ndarray
    iterations: int
    converged: bool


def shrink(X: np.ndarray, tau) -> np.ndarray:
    """Soft thresholding ``sign(x) max(|x| - tau, 0)`` (the l1 proximal map)."""
    return np.sign(X) * np.maximum(np.abs(X) - tau, 0.0)


def randomized_svd(X: np.ndarray, k: int, oversample: int = 10, power: int = 2,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Leading ``k`` singular triplets of a 2-D array by a randomized range finder
    (Halko, Martinsson and Tropp 2011) with ``power`` subspace iterations."""
    rng = np.random.default_rng(seed)
    q = X.shape[1]
    Omega = rng.standard_normal((q, min(k + oversample, q)))
    Q, _ = np.linalg.qr(X @ Omega)
    for _ in range(power):
        Q, _ = np.linalg.qr(X.T @ Q)
        Q, _ = np.linalg.qr(X @ Q)
    U, s, Vt = np.linalg.svd(Q.T @ X, full_matrices=False)
    return (Q @ U)[:, :k], s[:k], Vt[:k]


GRAM_RATIO = 4
"""A single matrix at least this many times taller than wide (or wider than
tall) is thresholded through the eigen-decomposition of its small Gram
matrix: about a tenth of the full SVD's time at 13 to 1 (a 6034 x 457 height
matrix of 457 frames: 0.08 s against 1.57 s per iteration). The ratio had
been 20, so the whole elephant animation paid the full SVD 39 times."""

PARTIAL_SVD_SHARE = 0.2
"""A randomized partial SVD is used while the singular values kept are at most
this share of a matrix's smaller side; past it the full SVD is faster."""


def _partial_svt(X: np.ndarray, tau: float, k: int, seed: int) -> tuple[np.ndarray, int] | None:
    """Singular value thresholding of one (p, q) matrix by randomized partial SVDs.

    Starts from the ``k`` leading singular triplets and doubles ``k`` until one
    of them falls at or below ``tau``, so that no singular value above ``tau``
    is missed. Returns ``(P, kept)``, or None once ``k`` passes
    :data:`PARTIAL_SVD_SHARE` of ``min(p, q)``.
    """
    limit = PARTIAL_SVD_SHARE * min(X.shape)
    while k <= limit:
        U, s, Vt = randomized_svd(X, k, seed=seed)
        keep = int((s > tau).sum())
        if keep < k:
            return (U[:, :keep] * (s[:keep] - tau)) @ Vt[:keep], keep
        k *= 2
    return None


def svt(X: np.ndarray, tau) -> np.ndarray:
    """Singular value thresholding ``U max(Sigma - tau, 0) V^T`` (the nuclear-norm
    proximal map) of a (b, p, q) stack of matrices, one ``tau`` per matrix.

    Stacks of thin matrices (``min(p, q) <= 4``, e.g. neighbourhoods of 3-D
    points or normals), and single matrices at least :data:`GRAM_RATIO` times
    taller than wide (e.g. stacked per-frame normals), go through the
    eigen-decomposition of the small Gram matrix, which is many times faster
    than an SVD.
    """
    tau = np.broadcast_to(np.asarray(tau, dtype=np.float64), X.shape[:-2])
    b, p, q = X.shape
    if min(p, q) <= 4:
        Xt = X if q <= p else np.swapaxes(X, 1, 2)
        w, W = np.linalg.eigh(np.einsum("bki,bkj->bij", Xt, Xt, optimize=False))
        sv = np.sqrt(np.maximum(w, 0.0))
        factor = np.where(sv > tau[:, None], (sv - tau[:, None]) / np.where(sv > 0, sv, 1.0), 0.0)
        M = np.einsum("bik,bk,bjk->bij", W, factor, W, optimize=False)
        out = np.einsum("bpi,bij->bpj", Xt, M, optimize=False)
        return out if q <= p else np.swapaxes(out, 1, 2)
    if b == 1 and max(p, q) >= GRAM_RATIO * min(p, q):
        # one tall (or wide) matrix: SVD through the small Gram matrix
        Xt = X[0] if q <= p else X[0].T
        w, W = np.linalg.eigh(Xt.T @ Xt)
        sv = np.sqrt(np.maximum(w, 0.0))
        t = float(tau[0])
        factor = np.where(sv > t, (sv - t) / np.where(sv > 0, sv, 1.0), 0.0)
        out = Xt @ ((W * factor) @ W.T)
        return (out if q <= p else out.T)[None]
    U, s, Vt = np.linalg.svd(X, full_matrices=False)
    s = np.maximum(s - tau[..., None], 0.0)
    return (U * s[..., None, :]) @ Vt


def _rpca_thin(D, lam, tol, max_iter, rho) -> RPCAResult:
    from geoproc.denoise.rpca_thin import rpca_thin_batch

    b, p, q = D.shape
    if lam is None:
        lam = 1.0 / np.sqrt(max(p, q))
    Dt = np.ascontiguousarray(D if q <= p else np.swapaxes(D, 1, 2))
    P = np.empty_like(Dt)
    S = np.empty_like(Dt)
    iters = np.zeros(b, dtype=np.int64)
    conv = np.zeros(b, dtype=np.bool_)
    rpca_thin_batch(Dt, float(lam), float(tol), int(max_iter), float(rho), P, S, iters, conv)
    if q > p:
        P, S = np.swapaxes(P, 1, 2), np.swapaxes(S, 1, 2)
    return RPCAResult(P=P, S=S, iterations=int(iters.max(initial=0)), converged=bool(conv.all()))


def rpca(
    D: np.ndarray,
    lam: float | None = None,
    tol: float = 1e-7,
    max_iter: int = 500,
    rho: float = 1.5,
    partial_svd_above: int = 400,
) -> RPCAResult:
    """Split ``D`` into a low-rank and a sparse part.

    Solves ``min |P|_* + lam |S|_1  s.t.  D = P + S`` by inexact ALM: alternate
    singular value thresholding of ``D - S + Y/mu`` at ``1/mu`` (P step) and soft
    thresholding of ``D - P + Y/mu`` at ``lam/mu`` (S step), update the
    multiplier ``Y += mu (D - P - S)`` and grow ``mu`` by ``rho``; stop when
    ``|D - P - S|_F <= tol |D|_F``.

    Parameters
    ----------
    D : (p, q) or (b, p, q) float array
        One matrix, or a batch of b matrices solved independently (used for
        the many small neighbourhood matrices of point clouds and patches;
        batches of thin matrices, ``min(p, q) <= 4``, run compiled and in
        parallel, each with its own stopping test).
    lam : float, optional
        Sparsity weight; default ``1 / sqrt(max(p, q))``.
    tol : float
        Relative residual at which to stop (1e-7 as in the review).
    max_iter : int
        Iteration cap.
    rho : float
        Growth factor of the penalty mu.
    partial_svd_above : int
        A single matrix with ``min(p, q)`` above this uses a randomized partial
        SVD whose rank adapts to the number of singular values kept (as in the
        reference implementation); smaller ones use the full thin SVD.

    Returns
    -------
    RPCAResult
    """
    D = np.asarray(D)
    if np.iscomplexobj(D) or not (np.issubdtype(D.dtype, np.number) or D.dtype == bool):
        raise ValueError(f"rpca needs a real matrix, got dtype {D.dtype}")
    D = D.astype(np.float64)
    if D.ndim not in (2, 3) or D.size == 0:
        raise ValueError(f"rpca needs a (p, q) matrix or a (b, p, q) batch with entries, got shape {D.shape}")
    if not np.isfinite(D).all():
        raise ValueError(f"rpca needs finite entries; {int((~np.isfinite(D)).sum())} are not")
    if lam is not None and not lam > 0:
        raise ValueError(f"rpca: lam must be > 0, got {lam}")
    if not rho > 1:
        raise ValueError(f"rpca: rho must be > 1 (the penalty grows by it), got {rho}")
    batched = D.ndim == 3
    if batched and min(D.shape[1:]) <= 4:
        return _rpca_thin(D, lam, tol, max_iter, rho)
    Db = D if batched else D[None]
    b, p, q = Db.shape
    if lam is None:
        lam = 1.0 / np.sqrt(max(p, q))
    normD = np.linalg.norm(Db, axis=(1, 2))
    safe = np.where(normD > 0, normD, 1.0)
    if not batched and max(p, q) >= GRAM_RATIO * min(p, q):
        X0 = Db[0]
        two = np.sqrt(np.linalg.eigvalsh(X0.T @ X0 if p >= q else X0 @ X0.T)[-1:])
    elif batched or min(p, q) <= partial_svd_above:
        two = np.linalg.norm(Db, ord=2, axis=(1, 2))
    else:
        two = randomized_svd(Db[0], 1)[1][:1]
    two = np.where(two > 0, two, 1.0)
    inf = np.abs(Db).max(axis=(1, 2)) / lam
    Y = Db / np.maximum(two, inf)[:, None, None]
    mu = 1.25 / two
    mu_bar = mu * 1e7
    S = np.zeros_like(Db)
    P = np.zeros_like(Db)
    partial = (not batched) and min(p, q) > partial_svd_above
    sv = 10
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        T = Db - S + Y / mu[:, None, None]
        thresholded = _partial_svt(T[0], 1.0 / mu[0], sv, it) if partial else None
        if thresholded is None:
            partial = False  # the rank kept has grown past the share where a partial SVD pays
            P = svt(T, 1.0 / mu)
        else:
            P, keep = thresholded
            P = P[None]
            sv = keep + 1 if keep < sv else keep + max(1, round(0.05 * min(p, q)))
        S = shrink(Db - P + Y / mu[:, None, None], (lam / mu)[:, None, None])
        Z = Db - P - S
        Y = Y + mu[:, None, None] * Z
        mu = np.minimum(mu * rho, mu_bar)
        err = np.linalg.norm(Z, axis=(1, 2)) / safe
        if (err <= tol).all():
            converged = True
            break
    if not batched:
        P, S = P[0], S[0]
    return RPCAResult(P=P, S=S, iterations=it, converged=converged)
