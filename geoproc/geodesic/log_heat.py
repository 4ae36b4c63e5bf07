"""Log-heat: the heat method driven by ``w = log u`` from the discrete log ODE.

The heat method only needs the direction of ``-grad u`` per face. ``w = log u``
comes from the log-ODE solver (:class:`geoproc.geodesic.log_ode.LogODESolver`,
intrinsic-Delaunay Laplacian, non-negative weights), which stays finite where
``u`` underflows. Per face, ``u`` is rescaled by the face's largest value,
``exp(w - max_face w)``, before taking the piecewise-linear gradient: exactly
the direction of ``grad u``, never 0/0. (``direction="log"`` uses the
piecewise-linear gradient of ``w`` itself instead.) Then ``X = -grad u / |grad u|``
and the Poisson solve ``L phi = div X`` with the mesh's own divergence and, by
default, the cotan Laplacian, the one consistent with it (``div grad = L``
exactly), shifted so the sources are at 0. Over ten sources on each of
armadillo, bunny, fertility and camelhead this pairing had a lower mean error
than the intrinsic-Delaunay Laplacian in the Poisson step on every mesh. On a
mesh with boundary, ``u`` is the average of the Neumann and Dirichlet
solutions (``boundary="average"``, as in the heat method), formed in log space
with ``logaddexp``.

On meshes with sliver triangles (``operators="auto"``: at least 0.5 % of the
faces with a corner angle below 5 degrees) the gradient, divergence and Poisson
Laplacian are taken on the intrinsic Delaunay triangulation instead
(:mod:`geoproc.geodesic.intrinsic`), where the extrinsic gradient's 1/height
entries no longer make the Poisson solution spike. On well-shaped meshes the
extrinsic pairing above was the more accurate one (bunny, fertility, armadillo
over ten sources each), so ``auto`` keeps it there.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.sparse as sp

from geoproc.geodesic.heat_operators import HeatOperators, heat_operators
from geoproc.geodesic.log_ode import LogODESolver, NegativeWeightsError, negative_weight_problem, off_diagonal_weights
from geoproc.mesh.topology import boundary_vertices


def face_heat_direction(coef: np.ndarray, F: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(m, 3) vectors parallel to ``grad exp(w)`` per face, formed without underflow.

    Each face uses ``exp(w - max_face w)``, a positive multiple of ``u`` on it.
    Faces with a vertex at ``w = -inf`` only (no heat) come back as 0, and so
    do faces where w is constant up to rounding
    (:func:`~geoproc.geodesic.operators.flat_within_rounding`, relative to
    ``max(|w|, 1)``): normalized, such a direction made log-heat on a
    tetrahedron give 1.08, 0.55 and 0.49 for three equidistant vertices.
    """
    out = np.zeros((coef.shape[1], coef.shape[0]))
    _face_heat_direction(np.ascontiguousarray(coef, dtype=np.float64), np.asarray(F, dtype=np.int64),
                         np.asarray(w, dtype=np.float64), out)
    return out


@numba.njit(cache=True)
def _face_heat_direction(coef, F, w, out):
    """:func:`face_heat_direction` into ``out`` (m, k), zero on entry; the flat
    test is :func:`~geoproc.geodesic.operators.flat_within_rounding`'s with floor 1."""
    tol = 64 * np.finfo(np.float64).eps
    for f in range(F.shape[0]):
        w0, w1, w2 = w[F[f, 0]], w[F[f, 1]], w[F[f, 2]]
        if np.isnan(w0) or np.isnan(w1) or np.isnan(w2):
            continue
        top, lo = max(w0, w1, w2), min(w0, w1, w2)
        if not np.isfinite(top):
            continue  # no heat on the face
        scale = max(top, -lo, 1.0)
        if np.isfinite(scale) and top - lo <= tol * scale:
            continue  # constant up to rounding
        s0, s1, s2 = np.exp(w0 - top), np.exp(w1 - top), np.exp(w2 - top)
        for a in range(coef.shape[0]):
            out[f, a] = coef[a, f, 0] * s0 + coef[a, f, 1] * s1 + coef[a, f, 2] * s2


class LogHeatSolver:
    """Precomputed log-heat distance: build once, :meth:`solve` per source set.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        Every vertex used by a face.
    t : float
        Total diffusion time (area unit), > 0.
    steps : int
        Backward-Euler steps of size ``t / steps``.
    laplacian : {"intrinsic-delaunay", "cotan"}
        Laplacian of the log-ODE (it must have non-negative weights).
    direction : {"heat", "log"}
        Face direction from ``grad u`` (rescaled per face) or ``grad w``.
    boundary : {"average", "neumann"}
        On a mesh with boundary, average the Neumann and Dirichlet heat, or
        Neumann only.
    poisson : {"cotan", "intrinsic-delaunay"}
        Laplacian of the Poisson step with extrinsic operators (with the
        mesh's own divergence).
    operators : {"auto", "extrinsic", "intrinsic"}
        Where the gradient, divergence and Poisson Laplacian live: on the mesh
        itself, or on its intrinsic Delaunay triangulation
        (:mod:`geoproc.geodesic.intrinsic`; its Laplacian then serves the
        Poisson step and the heat step: where an obtuse angle faces a boundary
        edge, that of the doubled cover folded onto the mesh, and on a
        non-orientable mesh, which has no such cover, the heat step takes
        :func:`~geoproc.geodesic.operators.intrinsic_delaunay_laplacian`,
        whose weights are non-negative). ``auto``: intrinsic when at least
        :data:`~geoproc.geodesic.intrinsic.SLIVER_SHARE` of the faces have a
        corner angle below :data:`~geoproc.geodesic.intrinsic.SLIVER_ANGLE_DEG`,
        or at least :data:`~geoproc.geodesic.intrinsic.NEGATIVE_WEIGHT_SHARE`
        of the cotan Laplacian's off-diagonal weight is negative.
        The choice made is in ``self.operators``.
    ops : HeatOperators, optional
        :func:`~geoproc.geodesic.heat_operators.heat_operators` of this mesh
        with these ``laplacian``, ``operators`` and ``poisson``, when the
        caller has them (the heat method re-solving its step in the log
        domain); built here otherwise.
    """

    def __init__(self, V: np.ndarray, F: np.ndarray, t: float, steps: int = 1,
                 laplacian: str = "intrinsic-delaunay", direction: str = "heat",
                 boundary: str = "average", poisson: str = "cotan", operators: str = "auto",
                 ops: HeatOperators | None = None):
        if ops is None:
            ops = heat_operators(V, F, laplacian, operators, poisson, compiled=True)
        L, M = ops.L, ops.M  # non-negative weights with intrinsic operators, as the log-ODE needs
        problem = negative_weight_problem(L, cotan=laplacian == "cotan" and ops.kind == "extrinsic")
        if problem:  # an InputError without the path: geodesic_distance names the mesh
            raise NegativeWeightsError(None, problem)
        self.M = M
        self.n, self.steps, self.direction = len(V), steps, direction
        self.operators, self.F, self.coef = ops.kind, ops.F, ops.coef
        self.G, self.D, self.poisson = ops.G, ops.D, ops.poisson
        self.log_ode = LogODESolver(L, M, t / steps)
        self.boundary = boundary_vertices(F) if boundary == "average" else np.zeros(0, dtype=np.int64)
        self._dirichlet = None
        self.lone, self.lone_decay = np.zeros(0, dtype=np.int64), np.zeros(0)
        if len(self.boundary):
            inner = np.ones(self.n, dtype=bool)
            inner[self.boundary] = False
            interior = np.flatnonzero(inner)
            Li = sp.csr_matrix(L)[interior][:, interior]
            # an interior vertex whose neighbours all lie on the boundary (u = 0
            # there) only decays: log u gains log(M_i / (M_i - dt L_ii)) per step
            lone = np.diff(off_diagonal_weights(Li).indptr) == 0
            self.lone = interior[lone]
            Ml = M[self.lone]
            with np.errstate(divide="ignore"):
                self.lone_decay = np.log(Ml) - np.log(Ml - (t / steps) * Li.diagonal()[lone])
            self.interior = interior[~lone]
            if len(self.interior):
                self._dirichlet = LogODESolver(Li[~lone][:, ~lone], M[self.interior], t / steps)

    def log_heat(self, sources: np.ndarray) -> np.ndarray:
        """(n,) ``w = log u`` at the final time from one unit of heat at each
        source (``u0 = 1/M_i`` there; see :meth:`geoproc.geodesic.heat.HeatMethodSolver.heat`)."""
        w = np.full(self.n, -np.inf)
        w[sources] = -np.log(self.M[sources])
        wn = w.copy()
        for _ in range(self.steps):
            wn, _ = self.log_ode.step(wn)
        if not len(self.boundary):
            return wn
        wd = np.full(self.n, -np.inf)
        if self._dirichlet is not None and np.isfinite(w[self.interior]).any():
            wi = w[self.interior]
            for _ in range(self.steps):
                wi, _ = self._dirichlet.step(wi)
            wd[self.interior] = wi
        wd[self.lone] = w[self.lone] + self.steps * self.lone_decay
        return np.logaddexp(wn, wd) - np.log(2.0)

    def distance_from_log_heat(self, w: np.ndarray, sources: np.ndarray) -> np.ndarray:
        """Normalize the face direction, Poisson-solve, shift so the sources are 0."""
        if self.direction == "log":
            g = (self.G @ np.where(np.isfinite(w), w, w[np.isfinite(w)].min())).reshape(len(self.coef), -1).T
        else:
            g = face_heat_direction(self.coef, self.F, w)
        return self.poisson.distance_from_direction(self.D, g, sources)

    def solve(self, sources: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (n,) to the nearest source and the ``w = log u`` it came from."""
        sources = np.asarray(sources, dtype=np.int64)
        w = self.log_heat(sources)
        return self.distance_from_log_heat(w, sources), w


def log_heat_distance(V: np.ndarray, F: np.ndarray, sources: np.ndarray, t: float, steps: int = 1,
                      laplacian: str = "intrinsic-delaunay") -> np.ndarray:
    """(n,) log-heat distance from ``sources`` (see :class:`LogHeatSolver`)."""
    return LogHeatSolver(V, F, t, steps, laplacian).solve(sources)[0]
