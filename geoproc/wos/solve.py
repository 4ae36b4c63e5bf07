"""Solve a 2D Laplace problem on a grid by Walk on Spheres/Stars, with control variates.

Methods
-------
naive
    Plain walks at every grid point.
cv-green, cv-angle
    Two passes: a fit pass (walks at ``fit_points`` spread points, ridge fit of
    Green or segment-angle kernels) and a residual pass (walks for ``g - c``,
    ``c`` added back).
npass
    cv-green's fit refined by Adam on fresh walk batches before the residual pass.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from geoproc.errors import InputError, UsageError
from geoproc.wos.domain import Domain
from geoproc.wos.expression import Expression, evaluate, translated
from geoproc.wos.fit import fit_points, make_kernels, neumann_samples, neumann_samples_and_ends, ridge_fit
from geoproc.wos.kernels import kernel_matrix, kernel_normal_matrix
from geoproc.wos.npass import adam_refine
from geoproc.wos.problem import WalkProblem, pass_seed

METHODS = ("naive", "cv-green", "cv-angle", "npass")
FIT_POINTS_PER_KERNEL = 8
"""The default number of fit points per kernel used (at most the grid's interior points)."""
_TAG_FIT, _TAG_RESIDUAL, _TAG_PILOT, _TAG_PILOT_PLAIN, _TAG_NPASS = 1, 2, 3, 4, 1000

UNRESOLVED_SPREAD = 1e-9
"""Walk spreads below this fraction of the data's size count as none in the
control variate's check (the float32 EXR resolves 6e-8 of a value; constant
data give plain walks no spread and a control variate one of rounding)."""

PILOT_WALKS = 32
"""Walks per fit point of the pass that checks a fitted control variate
(:func:`_control_variate_helps`)."""


@dataclass
class GridSpec:
    """Pixel-center grid: x = x0 + (col + 0.5) h, y = y1 - (row + 0.5) h; shape (ny, nx)."""

    x0: float
    y1: float
    h: float
    nx: int
    ny: int

    def points(self) -> np.ndarray:
        """(ny * nx, 2) pixel centers, row-major from the top row."""
        xs = self.x0 + (np.arange(self.nx) + 0.5) * self.h
        ys = self.y1 - (np.arange(self.ny) + 0.5) * self.h
        X, Y = np.meshgrid(xs, ys)
        return np.stack([X.ravel(), Y.ravel()], axis=1)


def suggested_epsilon(diagonal: float, deepest: float | None = None) -> float:
    """The stopping distance that is to a domain what the default 0.001 is to
    a unit square: 0.001 / sqrt(2) of the bounding-box ``diagonal``, and no
    more than 1/500 of the ``deepest`` grid point's distance to the boundary
    when it is known (a unit square's centre is 0.5 deep), so that a thin
    domain keeps points farther than 2 epsilon from its boundary. Domain
    length units."""
    eps = 1e-3 / np.sqrt(2.0) * diagonal
    return float(eps if deepest is None else min(eps, deepest / 500))


def grid_over(domain: Domain, n: int) -> GridSpec:
    """Square-pixel grid over the domain's bounding box, ``n`` pixels along its
    longer side and as many along the other as cover it (centred on the box:
    rounded to the nearest count, a 3 x 1 box at n = 16 had 5 rows, covering
    0.9375 of its height, and the domain's top and bottom were in no pixel)."""
    lo, hi = domain.bbox
    size = hi - lo
    h = float(size.max()) / n
    nx, ny = (max(1, int(np.ceil(size[k] / h - 1e-9))) for k in (0, 1))
    cx, cy = (lo + hi) / 2
    return GridSpec(float(cx - nx * h / 2), float(cy + ny * h / 2), h, nx, ny)


@dataclass
class WosResult:
    """Output of :func:`solve_laplace`.

    Attributes
    ----------
    U : (ny, nx) float64
        Estimates at pixel centers, NaN outside the domain.
    stderr : (ny, nx) float64
        Standard error of each estimate (NaN outside).
    exact : (ny, nx) float64 or None
        The declared exact solution (``exact=True``), NaN outside.
    scored : (ny, nx) bool
        Pixels the error metrics use (inside, farther than 2 eps from the boundary).
    grid : GridSpec
    metrics : dict
        Scalars for the report.
    sigma : (M,) float64 or None
        Control-variate coefficients.
    """

    U: np.ndarray
    stderr: np.ndarray
    exact: np.ndarray | None
    scored: np.ndarray
    grid: GridSpec
    metrics: dict = field(default_factory=dict)
    sigma: np.ndarray | None = None


def _control_variate_helps(problem, F: np.ndarray, ks, sigma: np.ndarray, u_fit: np.ndarray,
                           var_plain: np.ndarray | None, stream_seed, plain_seed) -> tuple[float, int, int]:
    """The variance of the walks with the fitted control variate over that of
    plain walks, averaged over the fit points F (k, 2): the plain variance
    ``var_plain`` (k,) from the fit pass (None when it had one walk per point,
    whose spread is not measured: then :data:`PILOT_WALKS` plain walks per
    point measure it, on ``plain_seed``), the other from :data:`PILOT_WALKS`
    walks per point with the control variate (a stream of its own, so the
    other passes draw what they drew before). Above 1 the control variate
    makes the estimate worse: fitted from few points (the grid caps them) it
    can fit the walks' noise (cv-angle on the disk at --grid 16 and 64 walks:
    rmse 0.14 against 0.075 for plain walks). Spreads below
    :data:`UNRESOLVED_SPREAD` of the fitted values' size count as 0 (constant
    data: plain walks have none, the control variate's is rounding), and 0
    is the ratio when the control variate's is so. Also returns the pass's
    walks and steps."""
    walks = steps = 0
    if var_plain is None:
        _, var_plain, st = problem.estimate_chunked(F, PILOT_WALKS, plain_seed)
        walks, steps = walks + len(F) * PILOT_WALKS, steps + int(st.sum())
    _, var_cv, st = problem.estimate_chunked(F, PILOT_WALKS, stream_seed, ks, sigma)
    walks, steps = walks + len(F) * PILOT_WALKS, steps + int(st.sum())
    floor = (UNRESOLVED_SPREAD * float(np.abs(u_fit).max(initial=0.0))) ** 2
    plain, with_cv = float(np.mean(var_plain)), float(np.mean(var_cv))
    if not with_cv > floor:  # (nan included: no measured spread to add)
        return 0.0, walks, steps
    return with_cv / max(plain, floor) if max(plain, floor) > 0 else float("inf"), walks, steps


def default_ridge(method: str) -> float:
    """Ridge weight of the fit unless given: 1 for the Green kernels (cv-green,
    npass), 0.1 for the angle kernels (cv-angle). On the 66 problems of
    bench/wos_domains.py (columns centred and scaled to unit standard
    deviation), the median RMSE ratio of cv-green to naive was 0.041, 0.035,
    0.031, 0.028, 0.027 and 0.031 at ridge 0.03, 0.1, 0.3, 1, 3 and 10 (worst
    0.055, 0.049, 0.045, 0.044, 0.061, 0.106); cv-angle's median went from
    0.159 at 0.1 to 0.167 at 1."""
    return 0.1 if method == "cv-angle" else 1.0


def solve_laplace(domain: Domain, boundary: Expression | None, *, flux: Expression | None = None,
                  method: str = "naive", walks: int = 128, grid: int = 256, eps: float = 1e-3,
                  kernels: int = 80, fit_walks: int = 128, ridge: float | None = None, seed: int = 0,
                  exact: bool = False, fit_points_n: int | None = None, npass_steps: int = 512,
                  npass_batch: int = 32, npass_walks: int = 16, npass_lr: float = 0.01,
                  progress: Callable[[float], None] | None = None) -> WosResult:
    """Estimate the harmonic function with the given boundary data on a pixel grid.

    Parameters
    ----------
    domain : Domain
    boundary : Expression or None
        Dirichlet data (None: the domain's per-vertex values).
    flux : Expression or None
        Neumann data ``du/dn`` (outward) on the domain's Neumann segments (None: zero).
    method : {"naive", "cv-green", "cv-angle", "npass"}
    walks : int
        Walks per grid point in the residual (or only) pass.
    grid : int
        Pixels along the longer side of the bounding box.
    eps : float
        Stopping distance, in the domain's length unit.
    kernels : int
        Number of control-variate kernels.
    fit_walks : int
        Walks per fit point.
    fit_points_n : int, optional
        Number of fit points (default ``FIT_POINTS_PER_KERNEL`` times the kernels used).
    ridge : float, optional
        Ridge weight (default :func:`default_ridge` of the method).
    seed : int
        Seed of every random stream.
    exact : bool
        ``boundary`` is harmonic: use it as the exact solution for error metrics.
    npass_steps, npass_batch, npass_walks, npass_lr : optional
        ``npass``: Adam steps, points per step, walks per point, learning rate
        (relative to the spread of the fitted control variate,
        :func:`geoproc.wos.npass.adam_refine`).
    progress : callable, optional
        ``progress(fraction_done)``.

    Returns
    -------
    WosResult
    """
    if method not in METHODS:
        raise UsageError(f"--method {method}: choose one of {', '.join(METHODS)}")
    for name, v in (("--walks", walks), ("--grid", grid), ("--kernels", kernels),
                    ("--fit-walks", fit_walks)):
        if v < 1:
            raise UsageError(f"{name} must be at least 1, got {v}")
    if not eps > 0:
        raise UsageError(f"--epsilon must be positive, got {eps}")
    if ridge is None:
        ridge = default_ridge(method)
    if not ridge >= 0:
        raise UsageError(f"--ridge must be non-negative, got {ridge}")
    if exact and boundary is None:
        raise UsageError("--exact needs --boundary 'EXPR' (the declared exact solution)")
    if method == "cv-angle" and domain.has_neumann:  # the domain file is what does not suit: name it
        raise InputError(domain.source, "has Neumann segments, and cv-angle supports Dirichlet-only domains (its "
                         "kernels' normal derivatives are singular on Neumann segments); use cv-green or npass")
    report = progress or (lambda f: None)
    shift = far_from_origin_shift(domain)
    if shift is not None:  # walk near 0, where positions keep their digits; the data keeps its coordinates
        boundary, flux = (None if e is None else translated(e, *shift) for e in (boundary, flux))
        domain = domain.translated(shift)
    problem = WalkProblem(domain, boundary, flux, eps)
    gs = grid_over(domain, grid)
    P = gs.points()
    d_all = problem.distance(P)
    # points on the boundary (up to round-off) count as inside, whatever the even-odd
    # test says of them: on a Dirichlet segment their walks stop at once and they take
    # the boundary value; on a Neumann segment they start 1e-9 of the diagonal inside
    # (wost.off_neumann_walls), where the points on a hole's top edge had been left NaN
    lo, hi = domain.bbox
    diagonal = float(np.linalg.norm(hi - lo))
    inside = domain.contains(P) | (d_all <= 1e-9 * diagonal)
    X = np.ascontiguousarray(P[inside])
    if len(X) == 0:
        raise UsageError(f"--grid {grid}: no grid point falls inside the domain; use a finer grid")
    depth = d_all[inside]
    # the points the error metrics use, and the fit's candidates: within 2 epsilon of the
    # boundary many walks stop at once
    deep = depth > 2 * eps
    if exact and not deep.any():  # known before any walk: refused now, not after them
        deepest = float(depth.max())
        raise InputError(str(domain.source), f"--exact: no grid point lies farther than 2 x epsilon ({2 * eps:.3g}) "
                         f"from the boundary (the farthest is {deepest:.3g} from it); --epsilon is in domain "
                         f"units (try {suggested_epsilon(diagonal, deepest):.2g}, as 0.001 is to a unit square), "
                         "or use a finer --grid")
    ue_inside = _declared_solution(boundary, X, domain) if exact else None
    # compile (or load cached code) outside the timed passes
    problem.load_kernels(X)

    metrics: dict = {"segments": domain.n_segments, "loops": len(domain.loops),
                     "neumann_segments": int(domain.neumann.sum()), "domain_area": domain.area,
                     "grid_width": gs.nx, "grid_height": gs.ny, "grid_points_inside": int(len(X)),
                     "pixel_size": gs.h, "walks": walks}
    total_walks = total_steps = 0
    walk_time = 0.0
    ks = sigma = None
    if method != "naive":
        t0 = time.perf_counter()
        cand = X[deep] if deep.any() else X
        ks = make_kernels(method, domain, kernels, problem.distance)
        F = fit_points(cand, fit_points_n or FIT_POINTS_PER_KERNEL * ks.M)
        u_fit, var_plain, st = problem.estimate_chunked(F, fit_walks, pass_seed(seed, _TAG_FIT),
                                                        progress=lambda f: report(0.05 * f))
        dPhi = hN = None
        if domain.has_neumann:
            # the residual's Neumann data is h - dc/dn: fit dc/dn to h on Neumann samples,
            # rows weighted by the kernel spacing so they read as value differences
            nb = max(8, int(round(len(F) * domain.perimeter_neumann / domain.perimeter)))
            Zb, Nb = neumann_samples(domain, nb)
            ell = domain.perimeter / ks.M
            dPhi = ell * kernel_normal_matrix(Zb, Nb, ks)
            hN = ell * (evaluate(flux, Zb[:, 0], Zb[:, 1], Nb[:, 0], Nb[:, 1]) if flux is not None
                        else np.zeros(nb))
        sigma, b, scale = ridge_fit(kernel_matrix(F, ks), u_fit, ridge, dPhi, hN)
        fit_seconds = time.perf_counter() - t0
        total_walks += len(F) * fit_walks
        total_steps += int(st.sum())
        walk_time += fit_seconds
        metrics.update({"kernels_used": ks.M, "fit_points": len(F), "fit_walks": fit_walks,
                        "fit_seconds": fit_seconds, "fit_steps": int(st.sum())})
        report(0.05)
        if method == "npass":
            t0 = time.perf_counter()
            sigma, b, nw, ns = adam_refine(
                problem, ks, sigma, b, scale, cand, lambda it: pass_seed(seed, _TAG_NPASS + it),
                steps=npass_steps, batch=npass_batch, walks=npass_walks, lr=npass_lr,
                progress=lambda f: report(0.05 + 0.15 * f), dPhi=dPhi, flux=hN)
            refine_seconds = time.perf_counter() - t0
            total_walks += nw
            total_steps += ns
            walk_time += refine_seconds
            metrics.update({"refine_seconds": refine_seconds, "refine_steps": ns,
                            "refine_iterations": npass_steps})
        t0 = time.perf_counter()
        ratio, pilot_walks, pilot_steps = _control_variate_helps(
            problem, F, ks, sigma, u_fit, var_plain if fit_walks > 1 else None, pass_seed(seed, _TAG_PILOT),
            pass_seed(seed, _TAG_PILOT_PLAIN))
        walk_time += time.perf_counter() - t0
        total_walks += pilot_walks
        total_steps += pilot_steps
        used = not ratio > 1.0
        metrics.update({"control_variate_variance_ratio": ratio, "control_variate_used": used})
        if not used:  # it adds variance: the residual pass runs plain walks
            ks = sigma = None
    start_frac = 0.0 if method == "naive" else (0.2 if method == "npass" else 0.05)
    t0 = time.perf_counter()
    mean, var, steps = problem.estimate_chunked(X, walks, pass_seed(seed, _TAG_RESIDUAL), ks, sigma,
                                                progress=lambda f: report(start_frac + (1 - start_frac) * f))
    residual_seconds = time.perf_counter() - t0
    bad = ~np.isfinite(mean)
    if bad.any():  # the data is singular between the sampled boundary points
        x, y = X[np.flatnonzero(bad)[0]] + domain.offset
        what = (f"the walk estimates at {int(bad.sum())} grid points are not finite (first at "
                f"x = {x:.6g}, y = {y:.6g}): the boundary data is not finite between the sampled "
                "points, or too large to average (beyond about 1e307)")
        data = ["--boundary" if boundary is not None else "the domain's values"]
        data += ["--neumann"] if flux is not None else []
        if data == ["the domain's values"]:  # the domain file alone
            raise InputError(str(domain.source), what)
        raise UsageError(f"{domain.source}: {what} (data from {' and '.join(data)})")
    total_walks += len(X) * walks
    total_steps += int(steps.sum())
    walk_time += residual_seconds
    metrics.update({"residual_seconds": residual_seconds, "residual_steps": int(steps.sum()),
                    "total_walks": total_walks, "total_steps": total_steps,
                    "steps_per_second": total_steps / walk_time if walk_time > 0 else float("nan"),
                    "residual_steps_per_second": int(steps.sum()) / residual_seconds
                    if residual_seconds > 0 else float("nan"),
                    "mean_steps_per_walk": float(steps.sum()) / (len(X) * walks)})
    se = np.sqrt(var / walks) if walks > 1 else np.full(len(var), np.nan)  # one walk: no spread to measure
    # over the points the error metrics use: within 2 epsilon of the boundary many walks stop
    # at once, with a standard error of 0 (on a 1 cm square, 112 of 256 points halved the mean)
    se_deep = se[deep] if deep.any() else se
    metrics["mean_standard_error"] = float(se_deep.mean())
    # the spread rmse should come to when the estimates are unbiased: where the standard error
    # varies over the grid, the plain mean understates it (a 1:1000 strip: rmse 3.8 times the mean)
    metrics["rms_standard_error"] = float(np.sqrt(np.mean(se_deep**2)))

    shape = (gs.ny, gs.nx)
    U = np.full(len(P), np.nan)
    U[inside] = mean
    SE = np.full(len(P), np.nan)
    SE[inside] = se
    scored = np.zeros(len(P), dtype=bool)
    scored[inside] = deep
    exact_img = None
    if exact:
        ue = np.full(len(P), np.nan)
        ue[inside] = ue_inside
        err = U[scored] - ue[scored]  # (not empty: refused before the walks)
        top = float(np.max(np.abs(err)))
        with np.errstate(over="ignore"):
            rmse = float(np.sqrt(np.mean(err**2)))
        if not np.isfinite(rmse) and np.isfinite(top):  # errors past 1e154 square to inf: scaled first
            rmse = top * float(np.sqrt(np.mean((err / top) ** 2)))
        metrics.update({"rmse": rmse, "max_abs_error": top,
                        "bias": float(np.mean(err)), "error_points": int(len(err)),
                        "declared_laplacian": declared_laplacian(boundary, X, depth, diagonal, shift),
                        "declared_mean_value_gap": declared_mean_value_gap(boundary, X, depth, shift),
                        "declared_flux_gap": declared_flux_gap(boundary, flux, domain, diagonal,
                                                               float(np.ptp(ue_inside)), shift)})
        exact_img = ue.reshape(shape)
    if shift is not None:
        gs = GridSpec(float(gs.x0 + shift[0]), float(gs.y1 + shift[1]), gs.h, gs.nx, gs.ny)
    # where the image lies in the domain's coordinates: pixel (row, col) is centred at
    # (grid_left + (col + 0.5) h, grid_top - (row + 0.5) h), h = pixel_size
    metrics.update({"grid_left": gs.x0, "grid_top": gs.y1})
    return WosResult(U.reshape(shape), SE.reshape(shape), exact_img, scored.reshape(shape), gs,
                     metrics, sigma)


FAR_FROM_ORIGIN = 1e3
"""A domain whose bounding-box centre lies farther than this many diagonals from
the origin is solved moved to the origin (:func:`far_from_origin_shift`)."""


def far_from_origin_shift(domain: Domain) -> np.ndarray | None:
    """The centre (2,) of the domain's bounding box when it lies farther than
    :data:`FAR_FROM_ORIGIN` diagonals from the origin, else None.

    Far from the origin a position keeps fewer digits relative to the domain:
    a unit square 1e12 away rounds positions to 1.2e-4, and cv-angle, whose
    kernels jump by 2 pi across their own segments, ended at an rmse of 0.25
    for 0.015 at the origin; at 9e14 the Green centres rounded back onto the
    boundary, none was left, and cv-green stopped with an internal error.
    The walks then run on the domain moved by this shift, and the boundary
    data is evaluated at the coordinates moved back.
    """
    lo, hi = domain.bbox
    centre = (lo + hi) / 2
    diagonal = float(np.linalg.norm(hi - lo))
    return centre if float(np.abs(centre).max()) > FAR_FROM_ORIGIN * diagonal else None


ROUNDING_MARGIN = 32.0
""":func:`declared_laplacian`, :func:`declared_mean_value_gap` and :func:`declared_flux_gap`
leave out this many machine epsilons of the size of the terms the expression sums
(:func:`_rounding`; over the step squared for the Laplacian, over the step for the flux):
what rounding the function's values alone can give."""

_EPS = float(np.finfo(np.float64).eps)

UNRESOLVED = 1e-5
"""Where a check finds nothing beyond rounding but rounding alone can give more than
this (relative, as the checks' values), it cannot tell harmonic from not at the level
that matters (a note at 1e-4) and is NaN: x*x - y*y 1e8 away from the origin for the
Laplacian's stencils. What it finds beyond rounding stands (x*x + y*y 1e4 away)."""

LAPLACIAN_STEP = 1e-3
"""Step of :func:`declared_laplacian`'s five-point stencil, in bounding-box diagonals."""


def declared_laplacian(expr, X: np.ndarray, depth: np.ndarray, diagonal: float,
                       offset: np.ndarray | None = None) -> float:
    """How far the declared solution ``expr`` is from harmonic at the grid points
    X (k, 2) whose distance to the boundary is ``depth`` (k,): the largest
    Laplacian, from five-point stencils of steps s and 2s (s =
    :data:`LAPLACIAN_STEP` diagonals) combined to cancel their s² truncation
    (Richardson), less what rounding of the values can give
    (:func:`_rounding` over the step squared),
    times the diagonal squared, over the range of ``expr`` there (NaN where
    it finds nothing beyond rounding and rounding can give more than
    :data:`UNRESOLVED`). Dimensionless: 1e-9 or less for a harmonic function far from its
    singularities, up to a few 1e-6 for a dipole centred in a hole of 0.01
    (its stencils' rounding and s⁴ terms), of order 1 for one that is not
    (x² + y² on the unit square: 4; log r with r = 0 inside the unit disk:
    5e-6 to 40, depending on how near a grid point comes, which
    :func:`declared_mean_value_gap` does not depend on). Points nearer the
    boundary than 40 steps are left out (a log r beside its hole); NaN when
    none is left."""
    s = LAPLACIAN_STEP * diagonal
    P = X[depth > 40 * s]
    if len(P) > 4096:  # an even subsample: the check stays cheap on any grid
        P = P[:: len(P) // 4096 + 1]
    if not len(P) or not s > 0:
        return float("nan")
    x, y = P[:, 0], P[:, 1]
    u = evaluate(expr, x, y)

    def stencil(t):
        e, w, n, so = (evaluate(expr, x + t, y), evaluate(expr, x - t, y), evaluate(expr, x, y + t),
                       evaluate(expr, x, y - t))
        return (e + w + n + so - 4 * u) / (t * t), np.hypot(e - w, n - so) / (2 * t)

    with np.errstate(over="ignore", invalid="ignore"):
        (near, grad), (far, _) = stencil(s), stencil(2 * s)
        lap = np.abs((4 * near - far) / 3)
        # what rounding the values alone gives (about 11 eps |f| / s^2), with a margin: far from
        # the origin x*x - y*y had read 67 at 1e12 and got the note that it is not harmonic
        floor = _rounding(u, grad, P, offset) / (s * s)
        lap = np.maximum(lap - floor, 0.0)
        span = float(np.ptp(u))
        if not span > 0:
            return float(np.max(lap) > 0)
        return _resolved(float(np.max(lap)) * diagonal**2 / span, float(np.max(floor)) * diagonal**2 / span)


MEAN_VALUE_NODES = 64
"""Points on each circle of :func:`declared_mean_value_gap` (the trapezoid rule on a
circle of half the distance to the boundary is exact to about 2^-64 for a harmonic function)."""

MEAN_VALUE_POINTS = 16384
"""At most this many grid points (an even subsample) centre circles in :func:`declared_mean_value_gap`."""


def declared_mean_value_gap(expr, X: np.ndarray, depth: np.ndarray, offset: np.ndarray | None = None) -> float:
    """How far the declared solution ``expr`` is from harmonic, by the mean
    value property: at each grid point x of X (k, 2) (an even subsample of
    at most :data:`MEAN_VALUE_POINTS`), the mean of ``expr`` over the circle
    of radius depth(x) / 2 (``depth``: distance to the boundary, (k,)) minus
    its value at x, less what rounding of the values can give
    (:func:`_rounding`); the largest gap over
    the range of ``expr`` at those points (NaN where it finds nothing beyond
    rounding and rounding can give more than :data:`UNRESOLVED`). Dimensionless: 0 for a harmonic function,
    whatever lies outside the domain; of order 1 for one that is not, including one harmonic but for a
    singular point inside (log r with r = 0 in the domain, which the
    Laplacian's stencils only see when a grid point comes near it). inf
    where ``expr`` is not finite on a circle; NaN when no point is inside."""
    keep = depth > 0
    P, rho = X[keep], 0.5 * depth[keep]
    if len(P) > MEAN_VALUE_POINTS:
        step = len(P) // MEAN_VALUE_POINTS + 1
        P, rho = P[::step], rho[::step]
    if not len(P):
        return float("nan")
    u = evaluate(expr, P[:, 0], P[:, 1])
    t = 2 * np.pi * np.arange(MEAN_VALUE_NODES) / MEAN_VALUE_NODES
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        cx = P[:, 0:1] + rho[:, None] * np.cos(t)
        cy = P[:, 1:2] + rho[:, None] * np.sin(t)
        ring = evaluate(expr, cx.ravel(), cy.ravel()).reshape(cx.shape)
        if not np.isfinite(ring).all():
            return float("inf")
        grad = np.abs(ring - u[:, None]).max(axis=1) / rho  # (a bound, within the mean value property's terms)
        floor = _rounding(np.maximum(np.abs(u), np.abs(ring).max(axis=1)), grad, P + rho[:, None], offset)
        gap = float(np.max(np.maximum(np.abs(ring.mean(axis=1) - u) - floor, 0.0)))
    span = float(np.ptp(u))
    if not span > 0:
        return float(gap > 0)
    return _resolved(gap / span, float(np.max(floor)) / span)


FLUX_SAMPLES = 1024
"""Points on the Neumann segments where :func:`declared_flux_gap` compares the declared
function's normal derivative with the flux."""

FLUX_STEP = 1e-4
"""Step of :func:`declared_flux_gap`'s one-sided difference, in bounding-box diagonals."""


def declared_flux_gap(expr, flux, domain: Domain, diagonal: float, span: float,
                      offset: np.ndarray | None = None) -> float:
    """How far the declared solution ``expr`` is from the Neumann data: at
    :data:`FLUX_SAMPLES` points spread over the Neumann segments, its
    derivative along the outward normal (a second-order one-sided difference
    of step :data:`FLUX_STEP` diagonals, from inside, or a hundredth of the
    distance to the segment's nearer end where that is less: a corner can be
    singular, as r^(2/3) at the apex of a reflex sector) minus the flux ``flux``
    (an expression; None is zero flux), less what rounding of the values can
    give; the largest, times the diagonal, over ``span`` (the declared
    function's range over the grid). Dimensionless: 0 for the solution of the
    mixed problem; of order 1 for one whose flux is another (y with flux 5 on
    a rectangle's top). Points where rounding (:func:`_rounding`, over the
    step) could pass :data:`UNRESOLVED` are left out; NaN without Neumann
    segments or when none is left; inf where a value is not finite."""
    if not domain.has_neumann:
        return float("nan")
    Z, N, ends = neumann_samples_and_ends(domain, FLUX_SAMPLES)
    d = np.minimum(FLUX_STEP * diagonal, 0.01 * ends)
    keep = d > 0
    Z, N, d = Z[keep], N[keep], d[keep]
    if not len(Z):
        return float("nan")
    with np.errstate(over="ignore", invalid="ignore"):
        f0, f1, f2 = (evaluate(expr, *(Z - k * d[:, None] * N).T) for k in (0, 1, 2))
        dudn = (3 * f0 - 4 * f1 + f2) / (2 * d)
        h = evaluate(flux, Z[:, 0], Z[:, 1], N[:, 0], N[:, 1]) if flux is not None else np.zeros(len(Z))
        if not (np.isfinite(dudn).all() and np.isfinite(h).all()):
            return float("inf")
        size = np.maximum.reduce([np.abs(f0), np.abs(f1), np.abs(f2)])
        # the gradient's size over the segments, from differences of the full step (one shrunk
        # next to a segment's end can round to no difference at all) and the derivatives at hand
        D = FLUX_STEP * diagonal
        gx = evaluate(expr, Z[:, 0] + D, Z[:, 1]) - evaluate(expr, Z[:, 0] - D, Z[:, 1])
        gy = evaluate(expr, Z[:, 0], Z[:, 1] + D) - evaluate(expr, Z[:, 0], Z[:, 1] - D)
        grad = max(float(np.max(np.hypot(gx, gy))) / (2 * D), float(np.max(np.abs(h))), float(np.max(np.abs(dudn))))
        floor = _rounding(size, np.full(len(Z), grad), Z, offset) / d
        gaps = np.maximum(np.abs(dudn - h) - floor, 0.0)
    if not span > 0:
        return float(gaps.max() > 0)
    # a point where rounding alone could pass the level that matters (a step shrunk next to
    # a segment's end, far from the origin) tells nothing: left out, NaN when none is left
    resolved = floor * diagonal / span <= UNRESOLVED
    return float(gaps[resolved].max() * diagonal / span) if resolved.any() else float("nan")


def _rounding(value: np.ndarray, grad: np.ndarray, P: np.ndarray, offset: np.ndarray | None = None) -> np.ndarray:
    """What rounding can put in a function's ``value`` (k,) at points P (k, 2)
    (in the expression's coordinates: ``P + offset`` when the domain was moved
    towards the origin and the expression with it) where its gradient is
    about ``grad`` (k,): :data:`ROUNDING_MARGIN` epsilons of the value and of
    the gradient times the coordinates' size, since the terms the expression
    sums may be that large (x*x - y*y near (1e8, 1e8): each term 1e16, their
    difference 2e8)."""
    Q = P if offset is None else P + np.asarray(offset, dtype=np.float64)
    return ROUNDING_MARGIN * _EPS * (np.abs(value) + np.abs(grad) * np.abs(Q).max(axis=1))


def _resolved(value: float, floor: float) -> float:
    """A check's ``value`` beyond rounding, or NaN where it reads 0 but rounding
    (``floor``, relative as the value) could hide more than :data:`UNRESOLVED`."""
    return float("nan") if value == 0 and floor > UNRESOLVED else value


def _declared_solution(boundary, X: np.ndarray, domain: Domain) -> np.ndarray:
    """``--exact``: the declared solution ``boundary`` at the grid points X (k, 2)
    inside ``domain``, checked before any walk. A harmonic function is finite
    inside its domain; NaN or inf there had given null error metrics without a word."""
    source = domain.source
    ue = evaluate(boundary, X[:, 0], X[:, 1])
    bad = ~np.isfinite(ue)
    if bad.any():
        x, y = X[np.flatnonzero(bad)[0]] + domain.offset
        raise UsageError(f"--exact: --boundary is not finite at {int(bad.sum())} grid points inside {source} "
                         f"(first at x = {x:.6g}, y = {y:.6g}), so it is not the exact solution there")
    return ue
