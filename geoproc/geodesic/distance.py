"""One entry point for every geodesic method, with input checks and timings."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from geoproc.errors import InputError, UsageError, shown_number
from geoproc.geodesic.intrinsic import POISSON_NEEDLE_ANGLE
from geoproc.geodesic.names import (
    DEFAULT_LAPLACIAN,
    DEFAULT_OPERATORS,
    HEAT_UNDERFLOW,
    LAPLACIANS,
    METHODS,
    OPERATORS,
    SOLVERS,
)
from geoproc.geodesic.operators import laplacian_and_mass
from geoproc.mesh.topology import face_areas, mean_edge_length, referenced_vertices, vertex_components
from geoproc.mesh.validate import mesh_arrays, require_edge_manifold, require_manifold

#: Smallest face angle (radians) below which a mesh is refused, by what the
#: method would run on the input's own triangles: libigl's exact geodesic
#: (MMP) ran for minutes on 8x8 grids squashed to angles of 2e-6 to 7e-6 rad
#: (and a 20x20 grid at 7e-6); the heat method's Poisson step lost its
#: accuracy (largest error 6 % of the grid's length at 2e-7 rad, 80 % at
#: 1e-7, 0.2 % at 1e-6); varadhan's cotan solve gave 0.53 at 1e-8 rad and inf
#: at 1e-9, against 0.35 (the method's own bias) at 1e-7. Intrinsic paths
#: refuse only a surface that is mostly needles (more than half its faces
#: below 1e-7 rad): their Delaunay flips remove a sliver from a good mesh
#: (and a strip of 38 needles of 1e-9 rad in a 722-face grid), but no
#: triangulation removes the needles of a surface that is itself a thin
#: strip, and on one (every angle 3.5e-9 rad) libigl's flips did not return.
NEEDLE_ANGLE = {"exact": 1e-4, "poisson": POISSON_NEEDLE_ANGLE, "cotan": 1e-7, "intrinsic": 1e-7}
NEEDLE_SURFACE_FRACTION = 0.5
#: Below this angle (radians) a face is degenerate within rounding: the intrinsic
#: Delaunay test on it is decided by rounding, and libigl's flips did not return
#: (memory grew past 15 GB) on an icosphere squashed to 1e-16; 1e-15 still ran.
INTRINSIC_DEGENERATE_ANGLE = 1e-14
#: Methods that integrate a normalized gradient by a Poisson solve (distance up to a constant).
POISSON_METHODS = ("heat", "log-heat")
#: Methods that need an edge- and vertex-manifold mesh (MMP walks vertex fans).
NEEDS_MANIFOLD = ("exact",)
#: Methods that need every edge to have at most two faces (boundary detection,
#: per-face gradients); a vertex joining separate fans is fine for them.
NEEDS_EDGE_MANIFOLD = ("heat", "log-splitting", "log-heat")
#: exp(w) is 0 in double precision below this log value (smallest subnormal).
LOG_TINIEST = math.log(5e-324)


@dataclass
class GeodesicResult:
    """What :func:`geodesic_distance` returns.

    Attributes
    ----------
    distance : (n,) float array
        Distance to the nearest source (mesh length unit); +inf on vertices
        not connected to a source (and where a method's heat underflowed).
    t : float or None
        Diffusion time used (area unit); None for ``exact``.
    h : float
        Mean edge length.
    timings : dict
        ``setup`` (operators and factorizations, reusable for other sources)
        and ``solve`` (the part repeated per source set), seconds.
    stats : dict
        Scalars for the report: ``unreachable_vertices``, and per method
        ``zero_heat_vertices`` (u == 0), ``negative_heat_vertices``,
        ``min_log_heat``, ``log_heat_below_double`` (w < log 5e-324, i.e.
        exp(w) underflows), ``iterations``.
    """

    distance: np.ndarray
    t: float | None
    h: float
    timings: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)


MAX_TIME_FACTOR = 1e12
"""Largest t / h^2 accepted: beyond it ``M + t L`` is numerically singular in
double precision (the heat and log-domain solves lose the solution)."""


def diffusion_time(h: float, time_factor: float | None = 1.0, time: float | None = None) -> float:
    """``t = time`` when given, else ``time_factor * h**2`` (area units); UsageError
    unless positive, finite and at most ``MAX_TIME_FACTOR * h**2``."""
    if time is not None:
        if not (math.isfinite(time) and time > 0):
            raise UsageError(f"--time must be a positive finite number, got {time}")
        if time > MAX_TIME_FACTOR * h * h:
            raise UsageError(f"--time {shown_number(time)} is more than {MAX_TIME_FACTOR:g} h^2 = "
                             f"{shown_number(MAX_TIME_FACTOR * h * h)} (h = {h:g}, the mean edge length); "
                             "the diffusion would be numerically singular")
        return float(time)
    c = 1.0 if time_factor is None else time_factor
    if not (math.isfinite(c) and c > 0):
        raise UsageError(f"--time-factor must be a positive finite number, got {c}")
    if c > MAX_TIME_FACTOR:
        raise UsageError(f"--time-factor {shown_number(c)} is more than {MAX_TIME_FACTOR:g}; "
                         "the diffusion would be numerically singular")
    t = float(c) * h * h
    if not t > 0:
        raise UsageError(f"t = {c:g} h^2 underflows to 0 (h = {h:g}, the mean edge length); use a larger "
                         "--time-factor")
    return t


def check_sources(sources, n: int, F: np.ndarray, path: str | None) -> np.ndarray:
    """Sources as an int array: at least one, each in [0, n) and used by a face."""
    items = np.asarray([] if sources is None else sources, dtype=object).reshape(-1)
    wrong = [s for s in items if isinstance(s, bool | np.bool_) or not isinstance(s, int | np.integer)]
    if wrong:
        raise UsageError(f"source vertices are integer indices, not {wrong[0]!r}")
    raw = [int(s) for s in items]
    if len(raw) == 0:
        raise UsageError("give at least one source vertex (--source I or --sources-file F)")
    bad = [s for s in raw if not 0 <= s < n]
    if bad:
        raise InputError(path, f"source vertex {bad[0]} is out of range "
                               f"(the mesh has {n} vertices, numbered from 0)")
    src = np.unique(np.asarray(raw, dtype=np.int64))
    iso = src[~referenced_vertices(F, n)[src]]
    if len(iso):
        raise InputError(path, f"source vertex {int(iso[0])} is isolated (no face uses it)")
    return src


def source_submesh(V: np.ndarray, F: np.ndarray, sources: np.ndarray):
    """The part of the mesh connected to a source.

    Returns ``(V2, F2, keep, src2)``: ``keep`` (k,) indexes the kept vertices
    (``V2 = V[keep]``), ``F2`` and ``src2`` are re-indexed into V2.
    """
    _, labels = vertex_components(F, len(V))
    reach = np.isin(labels, labels[sources]) & (labels >= 0)
    keep = np.flatnonzero(reach)
    remap = np.full(len(V), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    F2 = remap[F[reach[F[:, 0]]]]
    return V[keep], F2, keep, remap[sources]


def geodesic_distance(V: np.ndarray, F: np.ndarray, sources, method: str = "heat", *,
                      time_factor: float | None = 1.0, time: float | None = None, steps: int = 1,
                      laplacian: str | None = None, solver: str = "lu", operators: str | None = None,
                      path: str | None = None, progress=None, also_exact: bool = False,
                      heat_underflow: str = "log-domain", load_log=None) -> GeodesicResult:
    """Geodesic distance from ``sources`` by ``method`` (see :data:`METHODS`).

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    sources : int or sequence of int
        Source vertices; the distance is to the nearest one.
    method : str
        ``exact`` (MMP), ``heat`` (Crane et al.), ``varadhan``
        (``sqrt(-4T log u)``), ``log-splitting``, ``log-ode`` (discrete log
        ODE), ``log-heat`` (heat method on the log ODE).
    time_factor, time : float
        Diffusion time ``t = time`` if given, else ``time_factor * h^2`` with
        h the mean edge length. For ``heat`` it is the single step; for the
        others the total time reached in ``steps`` equal steps.
    steps : int
        Backward-Euler steps (>= 1); ``heat`` always uses one.
    laplacian : {"cotan", "intrinsic-delaunay"}, optional
        Default per :data:`DEFAULT_LAPLACIAN`.
    solver : {"lu", "newton", "cvxpy"}
        Log-ODE solver (``log-ode`` only; ``log-splitting`` always uses Clarabel).
    operators : {"auto", "extrinsic", "intrinsic"}, optional
        Where ``heat`` and ``log-heat`` take the gradient, divergence and
        Poisson Laplacian (see :class:`~geoproc.geodesic.log_heat.LogHeatSolver`);
        default per :data:`DEFAULT_OPERATORS`. The choice made is
        ``stats["operators"]``.
    path : str, optional
        Named in error messages.
    progress : callable, optional
        ``progress(fraction_done)``.
    load_log : geoproc.mesh.mesh.LoadLog, optional
        How the mesh was loaded: a face that repeats a vertex is then said to
        come from merging coincident positions where it does
        (:func:`geoproc.mesh.validate.require_edge_manifold`).
    also_exact : bool
        Also check, before solving, that the mesh suits ``exact`` (the command
        line's ``--reference exact``, named so in the error), so that the exact
        reference computed afterwards cannot fail on it after this solve.
    heat_underflow : {"log-domain", "keep"}
        ``heat`` only: where the heat step's u falls below the smallest normal
        double (2.2e-308; ``stats["underflow_heat_vertices"]``, zeros included)
        at a vertex connected to a source (a mesh many edges across for
        ``sqrt(t)``: the heat of one step decays by about e per edge at t =
        h^2), solve that
        step again in the log domain (:class:`~geoproc.geodesic.log_heat.LogHeatSolver`
        with one step, on the same operators: the same distances to rounding
        where u is representable, and a direction where it is not;
        ``stats["heat_step_in_log_domain"]``), or keep the plain step's result,
        whose direction is 0/0 there (a 1,200 × 3 strip from one end: largest
        distance 861 for 1,200).

    For the Poisson-based methods (:data:`POISSON_METHODS`) the distances are
    set to 0 at the sources and clipped at 0 from below
    (``stats["negative_distance_vertices"]`` counts the vertices clipped).
    """
    if method not in METHODS:
        raise UsageError(f"unknown method '{method}'; choose one of {', '.join(METHODS)}")
    if not isinstance(steps, int | np.integer) or steps < 1:
        raise UsageError(f"--steps must be at least 1, got {steps}")
    if solver not in SOLVERS:
        raise UsageError(f"unknown solver '{solver}'; choose one of {', '.join(SOLVERS)}")
    if heat_underflow not in HEAT_UNDERFLOW:
        raise UsageError(f"unknown heat underflow rule '{heat_underflow}'; choose one of {', '.join(HEAT_UNDERFLOW)}")
    if operators is not None and operators not in OPERATORS:
        raise UsageError(f"unknown operators '{operators}'; choose one of {', '.join(OPERATORS)}")
    if laplacian is not None and laplacian not in LAPLACIANS:
        raise UsageError(f"unknown Laplacian '{laplacian}'; choose cotan or intrinsic-delaunay")
    V, F = mesh_arrays(V, F, path, allow_point_cloud=True)
    if len(F) == 0:
        raise InputError(path, "is a point cloud (no faces); geodesic distance needs a triangle mesh")
    n = len(V)
    area = face_areas(V, F)
    if not (area > 0).any():
        raise InputError(path, "degenerate mesh: every face has zero area")
    src = check_sources(sources, n, F, path)
    h = mean_edge_length(V, F)
    t = None if method == "exact" else diffusion_time(h, time_factor, time)
    lap = None if method == "exact" else (laplacian or DEFAULT_LAPLACIAN[method])
    ops = operators or DEFAULT_OPERATORS.get(method)
    require_method_mesh(V, F, method, lap, ops, path, area=area, load_log=load_log)
    if also_exact and method != "exact":
        require_method_mesh(V, F, "exact", path=path, who="--reference exact", area=area, load_log=load_log)

    V2, F2, keep, s2 = source_submesh(V, F, src)
    stats: dict = {"unreachable_vertices": int(n - len(keep))}
    timings: dict = {}
    t0 = _now()
    try:
        d2 = _run_method(method, V2, F2, s2, t, steps, lap, solver, stats, timings, progress, path, ops,
                         heat_underflow)
    except InputError as exc:  # raised by a solver, which does not know the file
        if getattr(exc, "vertex", None) is not None:
            # log_ode.UnweightedVertexError names a vertex of the part connected to a
            # source; say which input vertex it is
            raise type(exc)(int(keep[exc.vertex]), path) from None
        if exc.path is None and path:
            raise InputError(path, exc.problem) from None
        raise
    timings.setdefault("solve", _now() - t0 - timings.get("setup", 0.0))
    if method in POISSON_METHODS:
        # the Poisson step fixes one constant, the mean over the sources: with several
        # sources, or near one on a coarse mesh, values dip below 0. A distance is 0 at
        # its sources and never negative (clipping never moves a value away from it)
        negative = d2 < 0
        negative[s2] = False  # a source is set to 0 whatever it came out as: not clipped
        stats["negative_distance_vertices"] = int(negative.sum())
        d2 = np.maximum(d2, 0.0)
        d2[s2] = 0.0
        if len(np.unique(s2)) < len(d2) and not (d2 > 0).any():
            # many steps to a long time leave the heat uniform to rounding: no direction is left
            raise InputError(path, f"the heat at t = {t:.3g} ({t / h**2:.3g} h^2) in {steps} step(s) is uniform "
                             "in double precision, so every distance came out 0; use a shorter time or fewer "
                             "--steps")
    d = np.full(n, np.inf)
    d[keep] = d2
    return GeodesicResult(d, t, h, timings, stats)


def require_method_mesh(V: np.ndarray, F: np.ndarray, method: str, lap: str | None = None,
                        ops: str | None = None, path: str | None = None, who: str | None = None,
                        area: np.ndarray | None = None, load_log=None) -> None:
    """InputError when the triangles (V (n, 3), F (m, 3)) do not suit ``method``
    run with Laplacian ``lap`` and operators ``ops``: not manifold where it needs
    a manifold, zero-area or too thin faces where it works on the input's own
    triangles, needles (:func:`_refuse_needles`). ``who`` names what needs it in
    the message (default ``method '<method>'``; ``--reference exact`` when the
    exact reference is checked before the chosen method runs); ``load_log``
    as for :func:`geodesic_distance`."""
    label = who or f"method '{method}'"
    if method in NEEDS_MANIFOLD:
        from geoproc.mesh import Mesh
        from geoproc.mesh.mesh import LoadLog

        # (no method takes the zero-area faces those would be with --no-clean: not offered)
        require_manifold(Mesh(V, F, log=load_log or LoadLog(path=path or "")), f"; {label} needs a manifold mesh",
                         keeps_flat_faces=False)
    if method in NEEDS_EDGE_MANIFOLD:
        require_edge_manifold(F, path, f"; {label} needs an edge-manifold mesh", load_log, keeps_flat_faces=False)
    # every method starts from the input's own triangles: the cotan ones use them, the
    # intrinsic Delaunay flips start from their edge lengths (faces whose lengths give zero
    # area, with a cross product that does not, kept libigl's flips allocating until killed)
    _refuse_flat_faces(V, F, path, label, area)
    _refuse_needles(V, F, method, lap, ops, path, who)  # names the method itself unless who is given


def _refuse_flat_faces(V, F, path, who: str, area: np.ndarray | None = None) -> None:
    """InputError naming the faces of zero area (``area``, computed when None),
    then those whose edge lengths give zero area (their cotangents are infinite)."""
    area = face_areas(V, F) if area is None else area
    if (area <= 0).any():
        k = int(np.flatnonzero(area <= 0)[0])
        raise InputError(path, f"{int((area <= 0).sum())} faces have zero area (first: face {k}); "
                               f"{who} needs non-degenerate triangles")
    from geoproc.geodesic.operators import infinite_cotan_faces

    thin = infinite_cotan_faces(V, F)  # their cotangents are infinite: heat gave NaN, exact never returned
    if len(thin):
        raise InputError(path, f"{len(thin)} faces are too thin (first: face {thin[0]}): their edge lengths "
                               f"give zero area, so their cotangents are infinite; {who} needs "
                               "non-degenerate triangles")


def _refuse_needles(V, F, method, lap, ops, path, who: str | None = None) -> None:
    """InputError when a face angle is below :data:`NEEDLE_ANGLE` for what
    the method would run on the input's own triangles (libigl's exact
    geodesic; the extrinsic Poisson step; a cotan solve)."""
    from geoproc.geodesic.operators import smallest_angles

    if method == "exact":
        key, what = "exact", ("libigl's exact geodesic (MMP" + (f", {who}" if who else "")
                              + ") does not return on some such meshes")
    elif method in POISSON_METHODS and ops == "extrinsic":
        key, what = "poisson", f"method '{method}' with extrinsic operators loses its accuracy on such needles"
    elif method not in POISSON_METHODS and lap == "cotan":
        key, what = "cotan", (f"the cotan weights (up to 1/angle) leave method '{method}' without accuracy "
                              "(--laplacian intrinsic-delaunay flips slivers away)")
    else:
        key, what = "intrinsic", ("the surface is mostly needles, which no intrinsic triangulation removes, "
                                  "and libigl's intrinsic Delaunay flips did not return on such a surface")
    angle = smallest_angles(V, F)
    limit = NEEDLE_ANGLE[key]
    needles = np.flatnonzero(angle < limit)
    if key == "intrinsic" and len(needles) <= NEEDLE_SURFACE_FRACTION * len(F):
        limit = INTRINSIC_DEGENERATE_ANGLE
        needles = np.flatnonzero(angle < limit)
        what = ("such faces are degenerate within rounding, where the intrinsic Delaunay flips are decided by "
                "rounding and libigl's did not return on a surface squashed flat")
    if len(needles):
        k = int(needles[np.argmin(angle[needles])])
        raise InputError(path, f"{len(needles)} of {len(F)} faces have an angle below {limit:g} rad "
                               f"(smallest: face {k}, {angle[k]:.2g} rad); {what}")


def _refuse_needles_if_extrinsic(V, F, method, lap, asked, ran, path) -> None:
    """The needle check of the extrinsic operators (:func:`_refuse_needles`) when
    they ran although ``asked`` was ``intrinsic`` or ``auto``: ``auto`` keeps them on
    a mesh with few slivers, and the intrinsic triangulation does not apply to
    every mesh (not edge-manifold, or a negative weight left on an interior edge)."""
    if ran == "extrinsic" and asked != "extrinsic":
        _refuse_needles(V, F, method, lap, "extrinsic", path)


def _now() -> float:
    return time.perf_counter()


def _run_method(method, V, F, src, t, steps, lap, solver, stats, timings, progress, path=None, ops=None,
                heat_underflow="log-domain"):
    if method == "exact":
        from geoproc.geodesic.exact import exact_geodesic_distance

        timings["setup"] = 0.0
        return exact_geodesic_distance(V, F, src)
    if method == "heat":
        from geoproc.geodesic.heat import HeatMethodSolver

        a = _now()
        hs = HeatMethodSolver(V, F, t, lap, ops)
        timings["setup"] = _now() - a
        _setup_done(progress)
        stats["operators"] = hs.operators
        _refuse_needles_if_extrinsic(V, F, method, lap, ops, hs.operators, path)
        a = _now()
        d, u = hs.solve(src)
        stats["zero_heat_vertices"] = int((u == 0).sum())
        stats["negative_heat_vertices"] = int((u < 0).sum())
        # below the smallest normal double u keeps fewer digits, down to none at 0
        stats["underflow_heat_vertices"] = int((np.abs(u) < np.finfo(np.float64).tiny).sum())
        stats["heat_step_in_log_domain"] = False
        if stats["underflow_heat_vertices"] and heat_underflow == "log-domain":
            d = _heat_step_in_log_domain(V, F, src, t, lap, hs, d, stats)
        timings["solve"] = _now() - a
        return d
    if method == "log-heat":
        from geoproc.geodesic.log_heat import LogHeatSolver

        a = _now()
        ls = LogHeatSolver(V, F, t, steps, lap, operators=ops)
        timings["setup"] = _now() - a
        _setup_done(progress)
        stats["operators"] = ls.operators
        _refuse_needles_if_extrinsic(V, F, method, lap, ops, ls.operators, path)
        a = _now()
        d, w = ls.solve(src)
        timings["solve"] = _now() - a
        _log_stats(w, stats)
        return d
    a = _now()
    L, M = laplacian_and_mass(V, F, lap)
    if method == "varadhan":
        from geoproc.geodesic.varadhan import heat_step_factor, varadhan_distance

        factor = heat_step_factor(L, M, t / steps)  # reusable for more sources: setup, as heat's
        timings["setup"] = _now() - a
        _setup_done(progress)
        d, u = varadhan_distance(L, M, src, t, steps, factor)
        stats["zero_heat_vertices"] = int((u == 0).sum())
        stats["negative_heat_vertices"] = int((u < 0).sum())
        return d
    if method == "log-ode":
        from geoproc.geodesic.log_ode import log_ode_stepper, negative_weight_problem, run_log_ode

        problem = negative_weight_problem(L)
        if problem:  # named with the mesh here, before any solver (the cvxpy one included)
            raise InputError(path, problem)
        if solver == "cvxpy":
            from geoproc.geodesic.log_ode_cvxpy import log_ode_steps_cvxpy

            timings["setup"] = _now() - a
            w, info = log_ode_steps_cvxpy(L, M, src, t, steps, progress)
            stats["solver_inaccurate_steps"] = info["inaccurate_steps"]
        else:
            step = log_ode_stepper(L, M, t / steps, solver)
            timings["setup"] = _now() - a
            w, info = run_log_ode(step, len(M), src, steps, progress)
            stats["iterations"] = info["iterations"]
        _log_stats(w, stats)
        return np.sqrt(np.maximum(0.0, -4.0 * t * w))
    if method == "log-splitting":
        from geoproc.geodesic.log_splitting import LogSplittingSolver

        sol = LogSplittingSolver(V, F, L, M, t, steps, path=path)
        timings["setup"] = _now() - a
        d, w = sol.solve(src, progress)
        _log_stats(w, stats)
        return d
    raise AssertionError(method)


SETUP_SHARE = 0.8
"""The share of a heat, log-heat or Varadhan run its setup (operators and
factorizations) is reported as: most of a single solve's time on large meshes."""


def _setup_done(progress) -> None:
    """Report the setup of a heat, log-heat or Varadhan run done (the bar had
    stayed at 0 % through a 30-second setup on a 690k-vertex mesh)."""
    if progress is not None:
        progress(SETUP_SHARE)


def _heat_step_in_log_domain(V, F, src, t, lap, hs, d, stats):
    """The heat method's distance with its heat step solved in the log domain
    (one step of :class:`~geoproc.geodesic.log_heat.LogHeatSolver` on the
    operators of ``hs``, a :class:`~geoproc.geodesic.heat.HeatMethodSolver`);
    ``d``, the plain step's, where the log ODE does not apply (negative cotan
    weights, or a vertex without a weighted edge). A time step too small for
    the log domain (t times the weights underflows) is an InputError: the
    plain step at that time is no distance either (a torus at c = 1e-310 had
    a largest distance of 0.2 for 3.4, with exit status 0)."""
    from geoproc.geodesic.log_heat import LogHeatSolver
    from geoproc.geodesic.log_ode import NegativeWeightsError, UnweightedVertexError

    try:
        d_log = LogHeatSolver(V, F, t, 1, lap, ops=hs.ops).solve(src)[0]
    except (NegativeWeightsError, UnweightedVertexError):  # the heat step ran; the log domain cannot take them
        return d
    stats["heat_step_in_log_domain"] = True
    return d_log


def _log_stats(w: np.ndarray, stats: dict) -> None:
    stats["min_log_heat"] = float(np.min(w))
    stats["log_heat_below_double"] = int((w < LOG_TINIEST).sum())
    stats["nonfinite_log_heat"] = int((~np.isfinite(w)).sum())
