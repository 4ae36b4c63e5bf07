"""Log-heat PDE by Strang-Marchuk splitting (Mattos Da Silva, Stein, Solomon 2024).

``w = log u`` of the heat equation solves ``dw/dt = Lap w + |grad w|^2``. Each
step of size ``dt`` does a half-step of implicit diffusion ``(M - dt/2 L) w' =
M w``, a full backward-Euler step of the nonlinear part ``w'' = w' + dt A |G
w''|^2`` (``G`` the face gradient, ``A`` the area-weighted face-to-vertex
average), posed as the convex program

    minimize sum_i M_i w_i   subject to   w >= w' + dt A |G w|^2

and solved by Clarabel (second-order cones, data built directly in sparse form:
through CVXPY's canonicalization the same program took 2.8 GB on a 3.5k-vertex
mesh), then another diffusion half-step. The program is solved in the scaled
variable ``x = (w - max w') / s`` with ``s = max w' - min w'``, so that ``x``
spans [-1, 0] and the constraint reads ``x >= x' + (dt s) A |G x|^2``: posed in
``w`` directly (values down to ``log floor`` ~ -690, gradients ~ 1e5) Clarabel
stops far from the optimum (every constraint slack by several units on bunny),
whereas the scaled program reaches it (an active constraint, a much lower
objective). The initial condition is ``log u0`` with ``u0`` the source
indicator clamped below at ``floor`` (``log 0`` is not a number). Distances are
``sqrt(-4 T w)`` as in Varadhan's formula.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.errors import InputError, UsageError
from geoproc.geodesic.operators import face_gradient_matrix, face_to_vertex_average, factor_sparse


def _clarabel():
    try:
        import clarabel
    except ImportError as exc:  # optional extra
        raise UsageError("log-splitting needs the optional package clarabel "
                         "(pip install 'geoproc[test]')") from exc
    return clarabel


def splitting_step_program(G: sp.spmatrix, A: sp.spmatrix, M: np.ndarray, k: float, rhs: np.ndarray):
    """Conic data of ``min M.x / sum M  s.t.  x >= rhs + k A |G x|^2`` for Clarabel.

    Variables ``z = [x (n), t (m), y (3m)]``: ``y = G x`` (zero cone),
    ``x - k A t >= rhs`` (non-negative cone) and ``|y_f|^2 <= t_f`` per face as
    the second-order cone ``|(2 y_f, t_f - 1)| <= t_f + 1``. Every block is
    sparse, so memory grows linearly with the mesh.

    Returns ``(P, q, Acon, b, cones)`` in Clarabel's ``Acon z + s = b, s in K`` form.
    """
    clarabel = _clarabel()
    n, m = G.shape[1], G.shape[0] // 3
    nz = n + 4 * m
    Y = sp.hstack([sp.csr_matrix(-G), sp.csr_matrix((3 * m, m)), sp.identity(3 * m, format="csr")])
    N = sp.hstack([-sp.identity(n, format="csr"), k * sp.csr_matrix(A), sp.csr_matrix((n, 3 * m))])
    # per face f the cone rows (t_f + 1, 2 y_f0, 2 y_f1, 2 y_f2, t_f - 1) = b - Acon z
    f = np.arange(m)
    rows = np.concatenate([5 * f, 5 * f + 1, 5 * f + 2, 5 * f + 3, 5 * f + 4])
    cols = np.concatenate([n + f, n + m + f, n + 2 * m + f, n + 3 * m + f, n + f])
    vals = np.concatenate([-np.ones(m), -2 * np.ones(3 * m), -np.ones(m)])
    C = sp.csr_matrix((vals, (rows, cols)), shape=(5 * m, nz))
    bc = np.zeros(5 * m)
    bc[0::5], bc[4::5] = 1.0, -1.0
    Acon = sp.vstack([Y, N, C]).tocsc()
    b = np.concatenate([np.zeros(3 * m), -rhs, bc])
    q = np.zeros(nz)
    q[:n] = M / M.sum()
    cones = [clarabel.ZeroConeT(3 * m), clarabel.NonnegativeConeT(n)] + [clarabel.SecondOrderConeT(5)] * m
    return sp.csc_matrix((nz, nz)), q, Acon, b, cones


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
    tol : float
        Clarabel's gap and feasibility tolerances (on the scaled program).
    path : str, optional
        Named in the error raised when Clarabel does not converge.
    """

    def __init__(self, V: np.ndarray, F: np.ndarray, L: sp.spmatrix, M: np.ndarray, T: float,
                 steps: int = 1, floor: float = 1e-300, tol: float = 1e-8, path: str | None = None):
        _clarabel()  # fail early when the optional package is missing
        self.n, self.steps, self.T, self.floor = len(V), steps, T, floor
        self.dt = T / steps
        self.M = M
        self._half = factor_sparse(sp.diags(M) - 0.5 * self.dt * sp.csr_matrix(L))
        self._G = sp.csr_matrix(face_gradient_matrix(V, F))
        self._A = face_to_vertex_average(V, F)
        self._tol = tol
        self.path = path
        self.status = None

    def nonlinear_step(self, w1: np.ndarray) -> np.ndarray:
        """Backward Euler of ``dw/dt = |grad w|^2`` from ``w1`` (the convex program)."""
        clarabel = _clarabel()
        shift = float(w1.max())  # the program is shift-invariant; keep values near 0
        scale = max(shift - float(w1.min()), 1.0)
        data = splitting_step_program(self._G, self._A, self.M, self.dt * scale, (w1 - shift) / scale)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = self._tol
        settings.max_iter = 100  # ~20-25 iterations when it converges
        sol = clarabel.DefaultSolver(*data, settings).solve()
        self.status = str(sol.status)
        if "Solved" not in self.status:  # Solved or AlmostSolved (reduced tolerances)
            raise InputError(self.path, f"log-splitting: Clarabel did not solve the nonlinear step "
                             f"({self.status}); it happens on meshes with sliver triangles (e.g. camelhead)")
        return scale * np.asarray(sol.x[:self.n], dtype=np.float64) + shift

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
