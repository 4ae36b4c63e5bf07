"""Solve ``A x = b`` for an M-matrix ``A`` and ``b >= 0`` entirely in log space.

An M-matrix (positive diagonal, non-positive off-diagonal entries, here
``A = M - dt L`` with ``L_ij >= 0``) has an LU factorization without row
interchanges whose factors keep that sign pattern. Forward and back
substitution then only ever add non-negative terms:

    y_i = b_i + sum_{j<i} |L_ij| y_j,      x_i = (y_i + sum_{j>i} |U_ij| x_j) / U_ii,

so they can be carried out on ``log y`` and ``log x`` with a running
(max-shifted) log-sum-exp, without cancellation and without underflow, even
where ``x`` is far below 1e-308. The factorization is computed once (in
ordinary arithmetic, where the entries are moderate) and reused for every
right-hand side.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.operators import factor_sparse


@numba.njit(cache=True)
def _log_forward(indptr, indices, logabs, beta):
    """log of the solution of a unit lower-triangular solve; strict part given."""
    n = len(beta)
    y = np.empty(n)
    for i in range(n):
        m = beta[i]
        s = 1.0 if m > -np.inf else 0.0
        for k in range(indptr[i], indptr[i + 1]):
            x = logabs[k] + y[indices[k]]
            if x == -np.inf:
                continue
            if x > m:
                s = s * np.exp(m - x) + 1.0
                m = x
            else:
                s += np.exp(x - m)
        y[i] = m + np.log(s) if s > 0.0 else -np.inf
    return y


@numba.njit(cache=True)
def _log_backward(indptr, indices, logabs, logdiag, beta):
    """log of the solution of an upper-triangular solve; strict part and diagonal given."""
    n = len(beta)
    x_out = np.empty(n)
    for i in range(n - 1, -1, -1):
        m = beta[i]
        s = 1.0 if m > -np.inf else 0.0
        for k in range(indptr[i], indptr[i + 1]):
            x = logabs[k] + x_out[indices[k]]
            if x == -np.inf:
                continue
            if x > m:
                s = s * np.exp(m - x) + 1.0
                m = x
            else:
                s += np.exp(x - m)
        x_out[i] = (m + np.log(s) if s > 0.0 else -np.inf) - logdiag[i]
    return x_out


class LogMMatrixSolver:
    """Factor an M-matrix once; solve with right-hand sides given by their logs.

    Parameters
    ----------
    A : (n, n) sparse
        Non-singular M-matrix with a symmetric sparsity pattern (e.g. ``M - dt L``).
    """

    def __init__(self, A: sp.spmatrix):
        lu = factor_sparse(A)
        self.perm_r, self.perm_c = lu.perm_r, lu.perm_c
        Lf = sp.tril(lu.L, -1, format="csr")
        Uf = sp.triu(lu.U, 1, format="csr")
        d = lu.U.diagonal()
        if (d <= 0).any() or (Lf.data > 0).any() or (Uf.data > 0).any():
            raise ValueError("matrix is not an M-matrix (LU factors lost the sign pattern)")
        Lf.sort_indices()
        Uf.sort_indices()
        with np.errstate(divide="ignore"):
            self._L = (Lf.indptr, Lf.indices, np.log(-Lf.data))
            self._U = (Uf.indptr, Uf.indices, np.log(-Uf.data), np.log(d))
        self.n = A.shape[0]
        self.factor_nnz = int(lu.L.nnz + lu.U.nnz)

    def solve_log(self, log_b: np.ndarray) -> np.ndarray:
        """``log x`` for ``A x = exp(log_b)`` (entries of ``log_b`` may be -inf)."""
        log_b = np.asarray(log_b, dtype=np.float64)
        bp = np.empty(self.n)
        bp[self.perm_r] = log_b
        y = _log_forward(*self._L, bp)
        z = _log_backward(*self._U, y)
        return z[self.perm_c]
