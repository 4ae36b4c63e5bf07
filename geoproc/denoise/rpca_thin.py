"""Compiled RPCA for large stacks of thin matrices (neighbourhoods of 3-D points or
normals: k x 3), each solved with its own inexact-ALM iteration and stopping test.

The singular value thresholding of a thin (p, q) matrix T uses the q x q Gram
matrix: with ``T^T T = W diag(s^2) W^T``, ``SVT(T, tau) = T W diag(max(s - tau, 0) / s) W^T``;
the small symmetric eigenproblem is solved by cyclic Jacobi rotations.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _jacobi_eigh(A, W):
    """Eigen-decomposition of a small symmetric matrix in place: on return the
    diagonal of A holds the eigenvalues and the columns of W the eigenvectors."""
    q = A.shape[0]
    for i in range(q):
        for j in range(q):
            W[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(60):
        off = 0.0
        scale = 0.0
        for i in range(q):
            scale += A[i, i] * A[i, i]
            for j in range(i + 1, q):
                off += A[i, j] * A[i, j]
        if off <= 1e-32 * scale or off == 0.0:
            return
        for i in range(q - 1):
            for j in range(i + 1, q):
                if A[i, j] == 0.0:
                    continue
                theta = (A[j, j] - A[i, i]) / (2.0 * A[i, j])
                t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(q):
                    aki = A[k, i]
                    akj = A[k, j]
                    A[k, i] = c * aki - s * akj
                    A[k, j] = s * aki + c * akj
                for k in range(q):
                    aik = A[i, k]
                    ajk = A[j, k]
                    A[i, k] = c * aik - s * ajk
                    A[j, k] = s * aik + c * ajk
                for k in range(q):
                    wki = W[k, i]
                    wkj = W[k, j]
                    W[k, i] = c * wki - s * wkj
                    W[k, j] = s * wki + c * wkj


@numba.njit(cache=True)
def _svt_thin(T, tau, P, G, W):
    p, q = T.shape
    for i in range(q):
        for j in range(q):
            acc = 0.0
            for k in range(p):
                acc += T[k, i] * T[k, j]
            G[i, j] = acc
    _jacobi_eigh(G, W)
    f = np.empty(q)
    for i in range(q):
        s = np.sqrt(max(G[i, i], 0.0))
        f[i] = (s - tau) / s if s > tau else 0.0
    # M = W diag(f) W^T, P = T M
    for a in range(p):
        for j in range(q):
            acc = 0.0
            for i in range(q):
                tw = 0.0
                for k in range(q):
                    tw += T[a, k] * W[k, i]
                acc += tw * f[i] * W[j, i]
            P[a, j] = acc


@numba.njit(parallel=True, cache=True)
def rpca_thin_batch(D, lam, tol, max_iter, rho, P_out, S_out, iters, converged):
    """Inexact-ALM RPCA of every D[t] (p x q, q small); see :func:`geoproc.denoise.rpca.rpca`."""
    b, p, q = D.shape
    for t in numba.prange(b):
        P = P_out[t]
        S = S_out[t]
        G = np.empty((q, q))
        W = np.empty((q, q))
        T = np.empty((p, q))
        Y = np.empty((p, q))
        X = np.empty((p, q))
        amax = 0.0
        for a in range(p):
            for j in range(q):
                amax = max(amax, abs(D[t, a, j]))
        # RPCA is scale-equivariant: far from 1 the matrix is solved divided by its
        # largest entry and the parts scaled back (its Gram matrix and the Jacobi
        # test's sums of squared Gram entries, the data's 4th power, overflowed or
        # underflowed beyond about 1e+-77 and the iteration stopped at once)
        c = amax if (amax > 1e60 or amax < 1e-60) and amax > 0.0 else 1.0
        normF = 0.0
        for a in range(p):
            for j in range(q):
                X[a, j] = D[t, a, j] / c if c != 1.0 else D[t, a, j]
                normF += X[a, j] * X[a, j]
                S[a, j] = 0.0
                P[a, j] = 0.0
        amax /= c
        normF = np.sqrt(normF)
        if normF == 0.0:
            iters[t] = 0
            converged[t] = True
            continue
        for i in range(q):
            for j in range(q):
                acc = 0.0
                for k in range(p):
                    acc += X[k, i] * X[k, j]
                G[i, j] = acc
        _jacobi_eigh(G, W)
        top = 0.0
        for i in range(q):
            top = max(top, G[i, i])
        two = np.sqrt(top)
        dual = max(two, amax / lam)
        for a in range(p):
            for j in range(q):
                Y[a, j] = X[a, j] / dual
        mu = 1.25 / two
        mu_bar = mu * 1e7
        done = False
        it = 0
        while it < max_iter and not done:
            it += 1
            inv = 1.0 / mu
            for a in range(p):
                for j in range(q):
                    T[a, j] = X[a, j] - S[a, j] + inv * Y[a, j]
            _svt_thin(T, inv, P, G, W)
            thr = lam * inv
            res = 0.0
            for a in range(p):
                for j in range(q):
                    v = X[a, j] - P[a, j] + inv * Y[a, j]
                    S[a, j] = v - thr if v > thr else (v + thr if v < -thr else 0.0)
                    z = X[a, j] - P[a, j] - S[a, j]
                    Y[a, j] += mu * z
                    res += z * z
            mu = min(mu * rho, mu_bar)
            if np.sqrt(res) <= tol * normF:
                done = True
        if c != 1.0:
            for a in range(p):
                for j in range(q):
                    P[a, j] *= c
                    S[a, j] *= c
        iters[t] = it
        converged[t] = done
