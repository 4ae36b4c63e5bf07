"""Reference solver of one log-ODE step: the convex program of the seed note.

    minimize    sum_i M_i w_i
    subject to  w_i >= log(M_i exp(w^n_i) + dt sum_{j != i} L_ij exp(w_j)) - log(M_i - dt L_ii)

written with exponential cones and solved by Clarabel through CVXPY. Its
minimizer is the backward-Euler step (the least supersolution of an M-matrix
system). Slow; used as the reference for :mod:`geoproc.geodesic.log_ode`.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from geoproc.errors import InputError, UsageError
from geoproc.geodesic.log_ode import LogStepSystem


def _cvxpy():
    try:
        import cvxpy as cp
    except ImportError as exc:  # optional extra
        raise UsageError("--solver cvxpy needs the optional packages cvxpy and clarabel "
                         "(pip install 'geoproc[test]')") from exc
    return cp


def log_ode_step_cvxpy(system: LogStepSystem, w_prev: np.ndarray, tol: float = 1e-10,
                       objective: str = "mass") -> tuple[np.ndarray, str]:
    """One log-ODE step (see :func:`geoproc.geodesic.log_ode.log_ode_step`) by Clarabel.

    Returns the (n,) log heat and CVXPY's status (``"optimal"``, or
    ``"optimal_inaccurate"`` where Clarabel stopped short of the tolerances;
    CVXPY's warning about it is not passed on, the caller reports the status).
    """
    cp = _cvxpy()
    n = system.n
    nnz = len(system.cols)
    b = system.logM + w_prev
    fin = np.flatnonzero(np.isfinite(b))
    k = np.arange(nnz)
    # exponent of edge term: a_ij - c_i + w_j - w_i
    De = sp.csr_matrix((np.concatenate([np.ones(nnz), -np.ones(nnz)]),
                        (np.concatenate([k, k]), np.concatenate([system.cols, system.rows]))), shape=(nnz, n))
    Re = sp.csr_matrix((np.ones(nnz), (system.rows, k)), shape=(n, nnz))
    Sf = sp.csr_matrix((np.ones(len(fin)), (fin, np.arange(len(fin)))), shape=(n, len(fin)))
    w = cp.Variable(n)
    edge = cp.exp(De @ w + (system.a - system.c[system.rows]))
    src = cp.exp((b[fin] - system.c[fin]) - w[fin])
    M = np.exp(system.logM)
    weights = M / M.sum() if objective == "mass" else np.full(n, 1.0 / n)
    prob = cp.Problem(cp.Minimize(weights @ w), [Re @ edge + Sf @ src <= 1])
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
        try:
            prob.solve(solver="CLARABEL", tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol, tol_ktratio=1e-8,
                       max_iter=500)
        except cp.error.SolverError:  # Clarabel stopped without a solution (large time steps)
            pass
    if w.value is None:  # an InputError without the path: geodesic_distance names the mesh
        raise InputError(None, f"log-ode --solver cvxpy: Clarabel did not solve the step ({prob.status or 'failed'}); "
                               "--solver lu solves the same step without it")
    return np.asarray(w.value, dtype=np.float64), str(prob.status)


def log_ode_steps_cvxpy(L: sp.spmatrix, M: np.ndarray, sources: np.ndarray, T: float,
                        steps: int = 1, progress=None) -> tuple[np.ndarray, dict]:
    """Same contract as :func:`geoproc.geodesic.log_ode.log_ode_steps`, by
    CVXPY/Clarabel; the info dict counts ``inaccurate_steps`` (steps Clarabel
    ended as "optimal_inaccurate")."""
    system = LogStepSystem(L, M, T / steps)
    w = np.full(len(M), -np.inf)
    w[np.asarray(sources)] = 0.0
    inaccurate = 0
    for k in range(steps):
        w, status = log_ode_step_cvxpy(system, w)
        inaccurate += status != "optimal"
        if progress is not None:
            progress((k + 1) / steps)
    return w, {"iterations": 0, "inaccurate_steps": inaccurate}
