"""Log-heat PDE by Strang-Marchuk splitting (Mattos Da Silva, Stein, Solomon 2024).

``w = log u`` of the heat equation solves ``dw/dt = Lap w + |grad w|^2``. Each
step of size ``dt`` does a half-step of implicit diffusion
``(M - dt/2 L) w' = M w``, a full backward-Euler step of the nonlinear part
``w'' = w' + dt A |G w''|^2`` (``G`` the face gradient, ``A`` the area-weighted
face-to-vertex average), posed as the convex program

    minimize sum_i M_i w_i   subject to   w >= w' + dt A |G w|^2

and solved by Clarabel through CVXPY (compiled once, re-solved every step),
then another diffusion half-step. The program is solved in the scaled variable
``x = (w - max w') / s`` with ``s = max w' - min w'``, so that ``x`` spans
[-1, 0] and the constraint reads ``x >= x' + (dt s) A |G x|^2``: posed in ``w``
directly (values down to ``log floor`` ~ -690, gradients ~ 1e5) Clarabel stops
far from the optimum (every constraint slack by several units on bunny),
whereas the scaled program reaches it (an active constraint, a much lower
objective). The initial condition is ``log u0`` with
``u0`` the source indicator clamped below at ``floor`` (``log 0`` is not a
number). Distances are ``sqrt(-4 T w)`` as in Varadhan's formula.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.operators import face_gradient_matrix, face_to_vertex_average, factor_sparse


def _cvxpy():
    from geoproc.geodesic.log_ode_cvxpy import _cvxpy as get

    return get()


class LogSplittingSolver:
    """Precomputed splitting scheme for the log-heat PDE.

    Parameters
    ----------
    V, F : mesh (every vertex used by a face)
    L : (n, n) sparse Laplacian, M : (n,) lumped mass
    T : float
        Total time (area unit), > 0.
    steps : int
        Number of splitting steps of size ``T / steps``.
    floor : float
        Lower clamp of the initial heat (``w0 = log max(u0, floor)``).
    """

    def __init__(self, V: np.ndarray, F: np.ndarray, L: sp.spmatrix, M: np.ndarray, T: float,
                 steps: int = 1, floor: float = 1e-300, tol: float = 1e-8):
        cp = _cvxpy()
        self.n, self.steps, self.T, self.floor = len(V), steps, T, floor
        dt = T / steps
        self.M = M
        self._half = factor_sparse(sp.diags(M) - 0.5 * dt * sp.csr_matrix(L))
        G = face_gradient_matrix(V, F)
        m = len(F)
        A = face_to_vertex_average(V, F)
        self.dt = dt
        self._x = cp.Variable(self.n)
        self._rhs = cp.Parameter(self.n)
        self._k = cp.Parameter(nonneg=True)
        g = [G[k * m:(k + 1) * m] @ self._x for k in range(3)]
        sq = cp.square(g[0]) + cp.square(g[1]) + cp.square(g[2])
        self._problem = cp.Problem(cp.Minimize((M / M.sum()) @ self._x),
                                   [self._k * (A @ sq) - self._x <= -self._rhs])
        self._tol = tol

    def nonlinear_step(self, w1: np.ndarray) -> np.ndarray:
        """Backward Euler of ``dw/dt = |grad w|^2`` from ``w1`` (the convex program)."""
        shift = float(w1.max())  # the program is shift-invariant; keep values near 0
        scale = max(shift - float(w1.min()), 1.0)
        self._rhs.value = (w1 - shift) / scale
        self._k.value = self.dt * scale
        t = self._tol
        self._problem.solve(solver="CLARABEL", tol_gap_abs=t, tol_gap_rel=t, tol_feas=t, max_iter=400)
        if self._x.value is None:
            raise RuntimeError(f"Clarabel did not solve the splitting step ({self._problem.status})")
        return scale * np.asarray(self._x.value, dtype=np.float64) + shift

    def log_heat(self, sources: np.ndarray, progress=None) -> np.ndarray:
        """(n,) ``w`` at time T from ``u0`` = indicator of the sources."""
        w = np.full(self.n, np.log(self.floor))
        w[np.asarray(sources)] = 0.0
        return self.evolve(w, progress)

    def evolve(self, w: np.ndarray, progress=None) -> np.ndarray:
        """(n,) ``w`` at time T from the finite initial log-heat ``w`` (n,)."""
        w = np.asarray(w, dtype=np.float64)
        for k in range(self.steps):
            w = self._half.solve(self.M * w)
            w = self.nonlinear_step(w)
            w = self._half.solve(self.M * w)
            if progress is not None:
                progress((k + 1) / self.steps)
        return w

    def solve(self, sources: np.ndarray, progress=None) -> tuple[np.ndarray, np.ndarray]:
        """Distance ``sqrt(max(0, -4 T w))`` (n,) and ``w``."""
        w = self.log_heat(sources, progress)
        return np.sqrt(np.maximum(0.0, -4.0 * self.T * w)), w


def log_splitting_distance(V: np.ndarray, F: np.ndarray, L: sp.spmatrix, M: np.ndarray,
                           sources: np.ndarray, T: float, steps: int = 1) -> np.ndarray:
    """(n,) distance by the splitting scheme (see :class:`LogSplittingSolver`)."""
    return LogSplittingSolver(V, F, L, M, T, steps).solve(sources)[0]
