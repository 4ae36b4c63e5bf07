"""The heat method of Crane, Weischedel and Wardetzky (2013).

Three steps with a time ``t`` (area unit; ``t = h^2`` is the paper's choice):
one backward-Euler heat step ``(M - t L) u = delta`` from the sources (1 at each
source vertex, 0 elsewhere: one unit of heat per source), the unit
field ``X = -grad u / |grad u|`` per face, and the Poisson solve
``L phi = div X``; ``phi`` is shifted so the sources are at 0. On a mesh with
boundary, ``u`` is the average of the Neumann and Dirichlet (u = 0 on the
boundary) solutions, as the paper recommends.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.heat_operators import heat_operators
from geoproc.geodesic.operators import factor_sparse, flat_within_rounding
from geoproc.mesh.topology import boundary_vertices


class HeatMethodSolver:
    """Precomputed heat method: factor once, then :meth:`solve` per source set.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        Every vertex must be used by a face.
    t : float
        Heat time step (area unit), > 0.
    laplacian : {"intrinsic-delaunay", "cotan"}
        Laplacian of the heat step (default intrinsic-delaunay: its weights
        are non-negative, so the heat stays positive; with the cotan weights of
        a mesh whose density changes, it went negative on up to half the
        vertices); with extrinsic operators the Poisson step uses the cotan
        Laplacian, the one consistent with the face gradient.
    operators : {"auto", "extrinsic", "intrinsic"}
        Gradient, divergence and Poisson Laplacian on the mesh (the paper's
        operators) or on its intrinsic Delaunay triangulation, as in
        :class:`geoproc.geodesic.log_heat.LogHeatSolver` (the heat step then on
        non-negative weights, see
        :func:`geoproc.geodesic.heat_operators.heat_operators`); ``auto``
        (default) goes intrinsic on meshes with slivers. The choice made is in
        ``self.operators``.
    """

    def __init__(self, V: np.ndarray, F: np.ndarray, t: float, laplacian: str = "intrinsic-delaunay",
                 operators: str = "auto"):
        self.n = len(V)
        ops = heat_operators(V, F, laplacian, operators)
        self.ops = ops
        self.operators, self.axes = ops.kind, len(ops.coef)
        self.G, self.D, self.poisson, self.F = ops.G, ops.D, ops.poisson, ops.F
        self.M = ops.M
        A = (sp.diags(ops.M) - t * ops.L).tocsc()
        self._neumann = factor_sparse(A)
        self.boundary = boundary_vertices(F)
        self._dirichlet = None
        if len(self.boundary):
            interior = np.ones(self.n, dtype=bool)
            interior[self.boundary] = False
            self.interior = np.flatnonzero(interior)
            Ai = A[self.interior][:, self.interior].tocsc()
            self._dirichlet = factor_sparse(Ai) if Ai.shape[0] else None

    def heat(self, sources: np.ndarray) -> np.ndarray:
        """(n,) heat ``u`` after one step from one unit of heat at each source
        (the paper's Kronecker delta right-hand side: ``u0 = 1/M_i`` there).

        Equal amounts matter with several sources: the heat of one backward-Euler
        step decays like ``exp(-d / sqrt(t))``, so a source that emits more (``u0 =
        1``, heat ``M_i``, its vertex area) pushes the meeting line of the fronts
        towards the others by ``sqrt(t) log(M_i / M_j)``."""
        b = np.zeros(self.n)
        b[sources] = 1.0
        u = self._neumann.solve(b)
        if len(self.boundary):
            ud = np.zeros(self.n)
            if self._dirichlet is not None:
                ud[self.interior] = self._dirichlet.solve(b[self.interior])
            u = 0.5 * (u + ud)
        return u

    def distance_from_heat(self, u: np.ndarray, sources: np.ndarray) -> np.ndarray:
        """Normalize ``-grad u``, Poisson-solve and shift so the sources are at 0.

        Faces where u is constant up to rounding get no direction
        (:func:`~geoproc.geodesic.operators.flat_within_rounding`)."""
        g = (self.G @ u).reshape(self.axes, -1).T
        g[flat_within_rounding(u[self.F])] = 0.0
        return self.poisson.distance_from_direction(self.D, g, sources)

    def solve(self, sources: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (n,) to the nearest source and the heat ``u`` it came from."""
        sources = np.asarray(sources, dtype=np.int64)
        u = self.heat(sources)
        return self.distance_from_heat(u, sources), u


def heat_method_distance(V: np.ndarray, F: np.ndarray, sources: np.ndarray, t: float,
                         laplacian: str = "intrinsic-delaunay", operators: str = "auto") -> np.ndarray:
    """(n,) heat-method distance from ``sources`` (see :class:`HeatMethodSolver`)."""
    return HeatMethodSolver(V, F, t, laplacian, operators).solve(sources)[0]
