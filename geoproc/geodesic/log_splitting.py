"""Log-heat PDE by Strang-Marchuk splitting (Mattos Da Silva, Stein, Solomon 2024).

``w = log u`` of the heat equation solves ``dw/dt = Lap w + |grad w|^2``. Each
step of size ``dt`` does a half-step of implicit diffusion ``(M - dt/2 L) w' =
M w``, a full backward-Euler step of the nonlinear part ``w'' = w' + dt A |G
w''|^2`` (``G`` the face gradient, ``A`` the area-weighted face-to-vertex
average), posed as the convex program

    minimize sum_i M_i w_i   subject to   w >= w' + dt A |G w|^2

and solved by Clarabel (second-order cones, data built directly in sparse form:
through CVXPY's canonicalization the same program took 2.8 GB on a 3.5k-vertex
mesh), then another diffusion half-step. The initial condition is ``log u0``
with ``u0`` the source indicator clamped below at ``floor`` (``log 0`` is not a
number). Distances are ``sqrt(-4 T w)`` as in Varadhan's formula.

Two changes of variables make the program solvable to Clarabel's default
accuracy; neither changes its solution:

* values: the program is solved in ``x = (w - max w') / s`` with ``s = max w' -
  min w'``, so that ``x`` spans [-1, 0]. Posed in ``w`` directly (values down
  to ``log floor`` ~ -690, gradients ~ 1e5) Clarabel stopped far from the
  optimum (every constraint slack by several units on bunny).
* lengths: the gradient is taken in units of the mean edge length ``h``
  (``h G``, and ``dt / h^2`` in the constraint), so that the program does not
  depend on the unit the mesh is stored in. In the mesh's own unit the
  gradient entries are of order ``1 / h`` (larger on sliver faces) and the
  nonlinear coefficient of order ``dt ~ h^2``; Clarabel then stopped with
  InsufficientProgress or MaxIterations whenever ``h`` was small: camelhead
  (h = 0.012, with slivers) and bunny (h = 0.0047) as stored, and the test
  grid, icosphere and torus once shrunk to ``h`` ~ 1e-3, while the same
  meshes converged at 10 and 100 times that size. In units of ``h`` each of
  them converges at every size (20-25 iterations on the stored meshes), with
  distances proportional to the size.

The gradient rows enter the cones as affine expressions of ``x`` (no auxiliary
copy ``y = G x`` with equality rows), which keeps Clarabel's KKT system at
``2n + 6m`` rows for ``n`` vertices and ``m`` faces.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.errors import InputError, UsageError
from geoproc.geodesic.operators import (
    face_gradient_matrix,
    face_to_vertex_average,
    factor_sparse,
    mean_edge_length,
)


def _clarabel():
    try:
        import clarabel
    except ImportError as exc:  # optional extra
        raise UsageError("log-splitting needs the optional package clarabel "
                         "(pip install 'geoproc[test]')") from exc
    return clarabel


def splitting_step_program(G: sp.spmatrix, A: sp.spmatrix, M: np.ndarray, k: float, rhs: np.ndarray):
    """Conic data of ``min M.x / sum M  s.t.  x >= rhs + k A |G x|^2`` for Clarabel.

    Parameters
    ----------
    G : (3m, n) sparse
        Face gradient (rows ``a m + f``: axis a of face f, the layout of ``igl.grad``),
        preferably in units of the mean edge length (entries of order 1).
    A : (n, m) sparse
        Face-to-vertex average.
    M : (n,) float
        Lumped vertex masses (the objective's weights).
    k : float
        Coefficient of the nonlinear term, in the unit of ``G`` (``dt / h^2`` for ``h G``).
    rhs : (n,) float
        Lower bound before the nonlinear term (the diffused ``x'``).

    Returns
    -------
    P, q, Acon, b, cones
        Clarabel's ``min q.z  s.t.  b - Acon z in K`` with variables ``z = [x (n), t (m)]``:
        ``x - k A t >= rhs`` (non-negative cone, n rows) and, per face f,
        ``|G_f x|^2 <= t_f`` as the second-order cone ``|(2 G_f x, t_f - 1)| <= t_f + 1``
        (5 rows: ``t_f + 1, 2 G_f x, t_f - 1``). Every block is sparse, so memory grows
        linearly with the mesh. ``P`` is the zero (n + m) square matrix.
    """
    clarabel = _clarabel()
    n, m = G.shape[1], A.shape[1]
    nz = n + m
    N = sp.hstack([-sp.identity(n, format="csr"), k * sp.csr_matrix(A)])
    C = _face_cone_rows(sp.coo_matrix(G), n, m)
    bc = np.zeros(5 * m)
    bc[0::5], bc[4::5] = 1.0, -1.0
    Acon = sp.vstack([N, C]).tocsc()
    b = np.concatenate([-rhs, bc])
    q = np.zeros(nz)
    q[:n] = M / M.sum()
    cones = [clarabel.NonnegativeConeT(n)] + [clarabel.SecondOrderConeT(5)] * m
    return sp.csc_matrix((nz, nz)), q, Acon, b, cones


def _face_cone_rows(G: sp.coo_matrix, n: int, m: int) -> sp.csr_matrix:
    """(5m, n + m) rows of ``-Acon`` for the cones ``(t_f + 1, 2 G_f x, t_f - 1)`` (constants in ``b``).

    Face f owns rows ``5f .. 5f + 4``; ``G`` is (3m, n) with rows ``a m + f``.
    """
    f = np.arange(m)
    axis, face = np.divmod(G.row, m)
    rows = np.concatenate([5 * f, 5 * face + 1 + axis, 5 * f + 4])
    cols = np.concatenate([n + f, G.col, n + f])
    vals = np.concatenate([-np.ones(m), -2.0 * G.data, -np.ones(m)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(5 * m, n + m))


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

    Attributes
    ----------
    h : float
        Mean edge length, the program's length unit.
    status, iterations : str, int
        Clarabel's status and iteration count in the last nonlinear step.
    """

    def __init__(self, V: np.ndarray, F: np.ndarray, L: sp.spmatrix, M: np.ndarray, T: float,
                 steps: int = 1, floor: float = 1e-300, tol: float = 1e-8, path: str | None = None):
        _clarabel()  # fail early when the optional package is missing
        self.n, self.steps, self.T, self.floor = len(V), steps, T, floor
        self.dt = T / steps
        self.M = M
        self._half = factor_sparse(sp.diags(M) - 0.5 * self.dt * sp.csr_matrix(L))
        self.h = mean_edge_length(V, F)  # the program's length unit (see the module docstring)
        self._G = sp.csr_matrix(self.h * face_gradient_matrix(V, F))
        self._A = face_to_vertex_average(V, F)
        self._tol = tol
        self.path = path
        self.status, self.iterations = None, None  # Clarabel's, from the last nonlinear step

    def nonlinear_step(self, w1: np.ndarray) -> np.ndarray:
        """Backward Euler of ``dw/dt = |grad w|^2`` from ``w1`` (n,): the convex program's ``w`` (n,).

        Raises InputError when Clarabel returns neither Solved nor AlmostSolved.
        """
        clarabel = _clarabel()
        shift = float(w1.max())  # the program is shift-invariant; keep values near 0
        scale = max(shift - float(w1.min()), 1.0)
        k = self.dt * scale / self.h**2
        data = splitting_step_program(self._G, self._A, self.M, k, (w1 - shift) / scale)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = self._tol
        settings.max_iter = 100  # ~20-25 iterations when it converges
        sol = clarabel.DefaultSolver(*data, settings).solve()
        self.status, self.iterations = str(sol.status), int(sol.iterations)
        if "Solved" not in self.status:  # Solved or AlmostSolved (reduced tolerances)
            raise InputError(self.path, f"log-splitting: Clarabel did not solve the nonlinear step "
                             f"({self.status})")
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
