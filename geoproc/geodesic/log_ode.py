"""The discrete log-heat ODE: backward Euler on ``w = log u`` without forming ``u``.

With ``(L u)_i = sum_{j~i} L_ij (u_j - u_i)`` and ``L_ij >= 0``, one backward
Euler step ``(M - dt L) u = M u^n`` reads, for every vertex i,

    w_i = log(M_i exp(w^n_i) + dt sum_{j != i} L_ij exp(w_j)) - log(M_i - dt L_ii),

a log-sum-exp fixed point, equivalent to the linear step up to ``w = log u``.

Two solvers of the same equations, both in log space:

- :class:`LogODESolver` (the default): factor the M-matrix ``M - dt L`` once
  per step size, then solve every step and source by forward and back
  substitution on logs (:mod:`geoproc.geodesic.log_lu`), followed by
  simplified-Newton refinement of the log-sum-exp residual with the same
  factors.
- :func:`log_ode_step`: Newton's method on
``g(w) = w + c - lse(w)``. Every quantity is formed in log space with a per-row
max shift, so nothing underflows: the Jacobian ``I - P``, with
``P_ij = dt L_ij exp(w_j - lse_i(w))`` in [0, 1], has the sparsity of
``M - dt L``. ``g`` is concave and its Jacobian is an M-matrix, so from the
start point below (the max-plus solution, a lower bound of the answer with
``g <= 0``) the Newton iterates increase monotonically to the solution.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from geoproc.errors import InputError, UsageError
from geoproc.geodesic.log_lu import LogMMatrixSolver
from geoproc.geodesic.operators import factor_sparse_lu, negative_offdiagonal_count


def negative_weight_problem(L: sp.spmatrix, cotan: bool = True) -> str | None:
    """Why the log-ODE cannot run on ``L`` (edges with negative weights), or None;
    ``cotan``: L is the mesh's cotan Laplacian (the message then points to the
    intrinsic Delaunay one)."""
    negative = negative_offdiagonal_count(L)
    if not negative:
        return None
    if cotan:
        return (f"{negative} edges have negative cotangent weights, and the log-ODE needs non-negative ones; "
                "use --laplacian intrinsic-delaunay")
    return f"{negative} edges have negative Laplacian weights, and the log-ODE needs non-negative ones"


def off_diagonal_weights(L: sp.spmatrix) -> sp.csr_matrix:
    """(n, n) the off-diagonal entries of L with the zero ones removed: a row
    left empty is a vertex no edge with a nonzero weight reaches."""
    L = sp.csr_matrix(L)
    off = (L - sp.diags(L.diagonal())).tocsr()
    off.eliminate_zeros()
    return off


class NegativeWeightsError(InputError):
    """The Laplacian has edges with negative weights (:func:`negative_weight_problem`
    says why), which the log-ODE cannot take."""


class UnweightedVertexError(InputError):
    """A vertex none of whose edges has a nonzero Laplacian weight: the log-ODE
    step cannot reach it. ``vertex`` is its index in the Laplacian's numbering."""

    def __init__(self, vertex: int, path: str | None = None):
        self.vertex = vertex
        super().__init__(path, f"vertex {vertex} has no neighbour with a nonzero Laplacian weight (isolated, "
                               "or only degenerate triangles around it)")


class LogStepSystem:
    """The constant parts of one log-ODE step of size ``dt``.

    Attributes
    ----------
    indptr, cols : CSR structure of the positive off-diagonal weights
    a : (nnz,) ``log(dt L_ij)``
    c : (n,) ``log(M_i - dt L_ii)``
    logM : (n,) ``log M_i``
    """

    def __init__(self, L: sp.spmatrix, M: np.ndarray, dt: float):
        problem = negative_weight_problem(L)
        if problem:
            raise UsageError(problem)
        L = sp.csr_matrix(L)
        n = L.shape[0]
        diag = L.diagonal()
        off = off_diagonal_weights(L)
        off.sort_indices()
        if np.any(np.diff(off.indptr) == 0):
            raise UnweightedVertexError(int(np.flatnonzero(np.diff(off.indptr) == 0)[0]))
        self.n, self.dt = n, dt
        self.indptr, self.cols = off.indptr, off.indices
        self.rows = np.repeat(np.arange(n), np.diff(off.indptr))
        weights = dt * off.data
        if not (weights > 0).all():
            raise InputError(None, f"time step {dt:g} is too small for this mesh: t times the Laplacian's "
                             "weights underflows to 0 in double precision")
        self.a = np.log(weights)
        self.c = np.log(M - dt * diag)
        with np.errstate(divide="ignore"):
            self.logM = np.log(M)

    def lse(self, w: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Row-wise ``log(exp(b_i) + sum_j exp(a_ij + w_j))`` with max shifting.

        Returns the (n,) values, the (nnz,) exponents ``a_ij + w_j`` and the
        shares ``exp(a_ij + w_j - lse_i)``.
        """
        e = self.a + w[self.cols]
        m = np.maximum(np.maximum.reduceat(e, self.indptr[:-1]), b)
        with np.errstate(invalid="ignore", over="ignore"):
            s = np.add.reduceat(np.exp(e - m[self.rows]), self.indptr[:-1]) + np.exp(b - m)
        val = m + np.log(s)
        return val, e, np.exp(e - val[self.rows])

    def max_plus_start(self, b: np.ndarray) -> np.ndarray:
        """The max-plus (tropical) solution ``w_i = max(b_i, max_j a_ij + w_j) - c_i``.

        A shortest-path problem (edge j -> i costs ``c_i - a_ij >= 0``), solved
        with Dijkstra from a virtual root. Satisfies ``g(w) <= 0``.
        """
        n = self.n
        fin = np.flatnonzero(np.isfinite(b))
        start = self.c[fin] - b[fin]
        lo = start.min()
        cost = np.maximum(self.c[self.rows] - self.a, 0.0) + 1e-300
        # edge from j = cols to i = rows; csgraph weights at [tail, head]
        tails = np.concatenate([self.cols, np.full(len(fin), n)])
        heads = np.concatenate([self.rows, fin])
        wts = np.concatenate([cost, start - lo + 1e-300])
        Gr = sp.csr_matrix((wts, (tails, heads)), shape=(n + 1, n + 1))
        dist = dijkstra(Gr, directed=True, indices=n)[:n]
        return -(dist + lo)


def log_ode_step(system: LogStepSystem, w_prev: np.ndarray, w_start: np.ndarray | None = None,
                 rtol: float = 1e-13, max_iter: int = 100) -> tuple[np.ndarray, int]:
    """One backward-Euler step of the log-heat ODE, solved by Newton in log space.

    Parameters
    ----------
    system : LogStepSystem
    w_prev : (n,) float array
        ``log u`` at the previous time; -inf allowed (u = 0 there), at least
        one entry finite.
    w_start : (n,) float array, optional
        Newton start; default the max-plus solution (:meth:`LogStepSystem.max_plus_start`).
    rtol : float
        Stop when every update is below ``rtol * max(1, |w_i|)``.

    Returns
    -------
    w : (n,) float array
        ``log u`` after the step (finite on every vertex connected to a
        finite entry of ``w_prev``).
    iterations : int
    """
    b = system.logM + w_prev
    w = system.max_plus_start(b) if w_start is None else np.asarray(w_start, dtype=np.float64).copy()
    n = system.n
    eye = sp.identity(n, format="csr")
    for it in range(1, max_iter + 1):
        val, _, share = system.lse(w, b)
        g = w + system.c - val
        P = sp.csr_matrix((share, system.cols, system.indptr), shape=(n, n))
        J = (eye - P).tocsc()
        step = -factor_sparse_lu(J).solve(g)
        w = w + step
        if np.all(np.abs(step) <= rtol * np.maximum(1.0, np.abs(w))):
            return w, it
    return w, max_iter


@numba.njit(cache=True)
def _lse_residual(indptr, cols, a, c, w, b):
    """Row by row, ``val_i = log(exp(b_i) + sum_j exp(a_ij + w_j))`` (shifted by
    the row's largest exponent; -inf when every term is 0) and the residual
    ``g_i = w_i + c_i - val_i`` (0 where ``w_i`` is not finite)."""
    n = len(w)
    val = np.empty(n)
    g = np.zeros(n)
    for i in range(n):
        m = b[i]
        for k in range(indptr[i], indptr[i + 1]):
            m = max(m, a[k] + w[cols[k]])
        if m == -np.inf:
            val[i] = -np.inf
        else:
            s = np.exp(b[i] - m)
            for k in range(indptr[i], indptr[i + 1]):
                s += np.exp(a[k] + w[cols[k]] - m)
            val[i] = m + np.log(s)
        if np.isfinite(w[i]):
            g[i] = w[i] + c[i] - val[i]
    return g, val


class LogODESolver:
    """One factorization of ``M - dt L``, reused for every step and source.

    Parameters
    ----------
    L : (n, n) sparse Laplacian with non-negative off-diagonal weights
    M : (n,) lumped mass
    dt : float
        Step size (area unit).
    """

    def __init__(self, L: sp.spmatrix, M: np.ndarray, dt: float):
        self.system = LogStepSystem(L, M, dt)
        self.lu = LogMMatrixSolver(sp.diags(M) - dt * sp.csr_matrix(L))
        self.fallbacks = 0

    def residual(self, w: np.ndarray, w_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``g = w + c - lse(w)`` (zero at the solution, 0 where w is not
        finite) and ``lse(w)``, the values of :meth:`LogStepSystem.lse`."""
        sy = self.system
        return _lse_residual(sy.indptr, sy.cols, sy.a, sy.c, np.asarray(w, dtype=np.float64),
                             sy.logM + w_prev)

    def step(self, w_prev: np.ndarray, rtol: float = 1e-14, max_refine: int = 3) -> tuple[np.ndarray, int]:
        """One backward-Euler step: ``w`` (n,) from ``w_prev`` (-inf allowed).

        Where the heat stays in the normal double range the factors solve in
        ordinary arithmetic (:meth:`LogMMatrixSolver.solve_log_in_range`);
        otherwise, or when that result's residual is not small, they solve on
        logs. The result is checked by its log-sum-exp residual and polished
        by simplified Newton (``J ~ diag(e^-lse) (M - dt L) diag(e^w)``, the
        same factors). If the residual is still not small (the factorization
        itself lost entries below the double range, which happens only at
        extremely small ``dt``), the step is redone by :func:`log_ode_step`
        (Newton, exact) and ``self.fallbacks`` counts it.

        Returns ``w`` and the number of refinement passes (or Newton
        iterations after a fallback).
        """
        log_b = self.system.logM + w_prev
        w = self.lu.solve_log_in_range(log_b)
        if w is not None:
            done = self._refine(w, w_prev, rtol, max_refine)
            if done is not None:
                return done
        done = self._refine(self.lu.solve_log(log_b), w_prev, rtol, max_refine)
        if done is not None:
            return done
        self.fallbacks += 1
        return log_ode_step(self.system, w_prev)

    def _refine(self, w: np.ndarray, w_prev: np.ndarray, rtol: float,
                max_refine: int) -> tuple[np.ndarray, int] | None:
        """``(w, passes)`` after up to ``max_refine`` simplified-Newton passes
        from a solve's ``w``, or None when its residual stays above 1e-10
        (relative to ``max(1, max |w|)``)."""
        fin = np.isfinite(w)
        for k in range(max_refine + 1):
            g, val = self.residual(w, w_prev)
            err = np.abs(g)
            if np.all(err <= 8 * rtol * np.maximum(1.0, np.abs(w))):
                return w, k
            if err.max() > 1e-6 or k == max_refine:
                break
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                yp = self.lu.solve_log(np.where(g > 0, val + np.log(np.where(g > 0, g, 1.0)), -np.inf))
                ym = self.lu.solve_log(np.where(g < 0, val + np.log(np.where(g < 0, -g, 1.0)), -np.inf))
                delta = -(np.exp(yp - w) - np.exp(ym - w))
            w = np.where(fin, w + np.nan_to_num(delta, nan=0.0, posinf=0.0, neginf=0.0), w)
        if err.max() <= 1e-10 * max(1.0, float(np.abs(w[fin]).max())):
            return w, max_refine
        return None


def log_ode_steps(L: sp.spmatrix, M: np.ndarray, sources: np.ndarray, T: float, steps: int = 1,
                  solver: str = "lu", progress=None) -> tuple[np.ndarray, dict]:
    """``log u`` at time ``T`` after ``steps`` equal backward-Euler steps from
    ``u0 = 1`` at the sources (0 elsewhere), never forming ``u``.

    Parameters
    ----------
    L : (n, n) sparse Laplacian with non-negative off-diagonal weights
    M : (n,) lumped mass
    sources : (k,) int array
    T : float
        Total time (area unit).
    steps : int
    solver : {"lu", "newton", "cvxpy"}
        Log-space LU with refinement (default), Newton, or the convex program
        (:mod:`geoproc.geodesic.log_ode_cvxpy`, optional dependency).
    progress : callable, optional
        ``progress(fraction_done)``.

    Returns
    -------
    w : (n,) float array
        ``log u(T)``; -inf only on vertices not connected to a source.
    info : dict
        ``iterations``: Newton iterations ("newton") or refinement passes
        ("lu"), summed over steps.
    """
    if solver == "cvxpy":
        from geoproc.geodesic.log_ode_cvxpy import log_ode_steps_cvxpy

        return log_ode_steps_cvxpy(L, M, sources, T, steps, progress)
    return run_log_ode(log_ode_stepper(L, M, T / steps, solver), len(M), sources, steps, progress)


def log_ode_stepper(L: sp.spmatrix, M: np.ndarray, dt: float, solver: str = "lu"):
    """Factor once for steps of size ``dt``; returns ``step(w) -> (w_next, iterations)``.

    ``solver`` is ``"lu"`` (:class:`LogODESolver`) or ``"newton"``
    (:func:`log_ode_step` on a :class:`LogStepSystem`).
    """
    if solver == "lu":
        return LogODESolver(L, M, dt).step
    if solver == "newton":
        system = LogStepSystem(L, M, dt)
        return lambda w: log_ode_step(system, w)
    raise ValueError(f"unknown log-ODE solver {solver!r}")


def run_log_ode(step, n: int, sources: np.ndarray, steps: int, progress=None) -> tuple[np.ndarray, dict]:
    """Apply ``step`` ``steps`` times from ``w = 0`` at the sources, ``-inf`` elsewhere.

    Returns ``(w, {"iterations": total})`` as :func:`log_ode_steps`.
    """
    w = np.full(n, -np.inf)
    w[np.asarray(sources)] = 0.0
    total = 0
    for k in range(steps):
        w, it = step(w)
        total += it
        if progress is not None:
            progress((k + 1) / steps)
    return w, {"iterations": total}
