"""The operators of the heat method's last two steps, on the mesh or on its intrinsic Delaunay triangulation."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.intrinsic import face_operators_triangulation, intrinsic_face_operators
from geoproc.geodesic.operators import (
    cotan_laplacian,
    divergence_matrix,
    face_gradient_coefficients,
    intrinsic_delaunay_laplacian,
    laplacian_and_mass,
    negative_offdiagonal_count,
    smallest_angles,
    stack_gradient_coefficients,
)
from geoproc.geodesic.poisson import PoissonSolver


@dataclass
class HeatOperators:
    """Laplacian and mass of the heat step, and gradient, divergence and Poisson
    solver of the distance step, all on one triangulation.

    Attributes
    ----------
    kind : {"extrinsic", "intrinsic"}
        The mesh itself, or its intrinsic Delaunay triangulation.
    L : (n, n) csr_matrix, M : (n,) float array
        Heat-step Laplacian and lumped mass (area unit); with intrinsic
        operators, off-diagonal weights are non-negative (see
        :func:`heat_operators`).
    F : (m, 3) int array
        Faces the gradient lives on (the intrinsic ones when ``kind`` is intrinsic).
    coef : (k, m, 3) float array
        Per-face gradient weights, k = 3 axes (extrinsic) or 2 (each intrinsic face's frame).
    G : (k m, n) csr_matrix, D : (n, k m) csr_matrix
        Face gradient and integrated divergence, ``D G`` the Poisson Laplacian.
    poisson : PoissonSolver
    """

    kind: str
    L: sp.csr_matrix
    M: np.ndarray
    F: np.ndarray
    coef: np.ndarray
    G: sp.csr_matrix
    D: sp.csr_matrix
    poisson: PoissonSolver


def heat_operators(V: np.ndarray, F: np.ndarray, laplacian: str, operators: str,
                   poisson: str = "cotan", compiled: bool = False) -> HeatOperators:
    """Build :class:`HeatOperators`.

    ``operators``: ``"extrinsic"`` (the heat step with ``laplacian``, the
    mesh's own gradient and divergence, the Poisson step with ``poisson``),
    ``"intrinsic"`` (everything on the intrinsic Delaunay triangulation, its
    Laplacian in both steps; where an obtuse angle faces a boundary edge, the
    triangulation of the doubled cover folded onto the mesh, see
    :func:`~geoproc.geodesic.operators.intrinsic_delaunay_mesh`: the mesh's own
    flips leave that edge a negative weight, weights of -400 along the hull of
    a Delaunay triangulation of random points, where the heat went negative
    on half the vertices and the mean error was 32 % of the largest distance;
    on a non-orientable mesh, which has no such cover, the mesh's own
    triangulation with the heat step on
    :func:`~geoproc.geodesic.operators.intrinsic_delaunay_laplacian`'s
    non-negative weights) or
    ``"auto"`` (intrinsic on meshes with slivers or
    strongly non-Delaunay triangles, see
    :func:`geoproc.geodesic.intrinsic.face_operators_triangulation`).
    Intrinsic falls back to extrinsic where the triangulation does not apply.
    ``compiled``: the per-face angles and gradient weights by the numba kernels of
    :mod:`geoproc.geodesic.face_kernels` (for callers that load numba anyway).
    """
    if len(F) == 0:  # libigl's operators crash on an empty face list
        raise ValueError("the mesh has no faces")
    angles, gradient_coefficients = smallest_angles, face_gradient_coefficients
    if compiled:
        from geoproc.geodesic.face_kernels import face_gradient_coefficients_compiled, smallest_angles_compiled

        angles, gradient_coefficients = smallest_angles_compiled, face_gradient_coefficients_compiled
    # auto may read the cotan Laplacian's negative weights; the extrinsic Poisson step then reuses it
    cotan = functools.cache(lambda: cotan_laplacian(V, F))
    tri = face_operators_triangulation(V, F, operators, angles, cotan)
    if tri is not None:
        coef, G, D = intrinsic_face_operators(tri.F, tri.l, len(V), tri.face_share)
        L, M = tri.L, tri.M
        if negative_offdiagonal_count(L):  # no cover (a non-orientable mesh): the heat step needs weights >= 0
            L, M = intrinsic_delaunay_laplacian(V, F)
        return HeatOperators("intrinsic", L, M, tri.F, coef, G, D, PoissonSolver(tri.L))  # D G = L
    L, M = laplacian_and_mass(V, F, laplacian)
    coef = gradient_coefficients(V, F)
    G = stack_gradient_coefficients(coef, F, len(V))
    if laplacian == poisson:
        Lp = L
    elif poisson == "cotan":
        Lp = cotan()  # without the mass the heat step needed
    else:
        Lp = laplacian_and_mass(V, F, poisson)[0]
    return HeatOperators("extrinsic", L, M, F, coef, G, divergence_matrix(V, F, G), PoissonSolver(Lp))
