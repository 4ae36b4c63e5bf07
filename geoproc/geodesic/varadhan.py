"""Varadhan's formula on backward-Euler heat: ``d = sqrt(-4 T log u)``."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.operators import factor_sparse


def heat_step_factor(L: sp.spmatrix, M: np.ndarray, dt: float):
    """The factorization of ``M - dt L`` (L (n, n) negative semi-definite, M (n,)
    lumped mass, dt in area units) that :func:`backward_euler_heat` solves with."""
    return factor_sparse((sp.diags(M) - dt * L).tocsc())


def backward_euler_heat(L: sp.spmatrix, M: np.ndarray, u0: np.ndarray, dt: float, steps: int,
                        factor=None) -> np.ndarray:
    """``steps`` backward-Euler steps ``(M - dt L) u_{k+1} = M u_k`` (one factorization).

    Parameters
    ----------
    L : (n, n) sparse Laplacian (negative semi-definite convention)
    M : (n,) lumped mass
    u0 : (n,) initial heat
    dt : float
        Step (area unit).
    steps : int
        Number of steps, >= 1.
    factor : optional
        :func:`heat_step_factor` of the same L, M and dt, when the caller has it.
    """
    lu = heat_step_factor(L, M, dt) if factor is None else factor
    u = np.asarray(u0, dtype=np.float64)
    for _ in range(steps):
        u = lu.solve(M * u)
    return u


def varadhan_from_heat(u: np.ndarray, T: float) -> np.ndarray:
    """``sqrt(max(0, -4 T log u))``; +inf where ``u <= 0`` (underflow or negative weights);
    +0.0 where ``u >= 1`` (``log u = 0`` made -0.0 there, which a PLY keeps with its sign)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(u > 0, np.log(np.where(u > 0, u, 1.0)), -np.inf)
    return np.sqrt(np.maximum(-4.0 * T * w, 0.0)) + 0.0


def varadhan_distance(L: sp.spmatrix, M: np.ndarray, sources: np.ndarray, T: float,
                      steps: int = 1, factor=None) -> tuple[np.ndarray, np.ndarray]:
    """Heat from ``u0 = 1`` at the sources over ``steps`` steps to time ``T``, then Varadhan
    (``factor``: :func:`heat_step_factor` of L, M and ``T / steps``, when the caller has it).

    Returns
    -------
    d : (n,) distance (+inf where u == 0)
    u : (n,) the heat at time T
    """
    u0 = np.zeros(len(M))
    u0[np.asarray(sources)] = 1.0
    u = backward_euler_heat(L, M, u0, T / steps, steps, factor)
    return varadhan_from_heat(u, T), u
