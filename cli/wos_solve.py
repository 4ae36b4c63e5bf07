"""``geoproc wos-solve``: 2D Laplace problems by Walk on Spheres/Stars with control variates."""

from __future__ import annotations

import os
from enum import StrEnum
from typing import Annotated

import numpy as np
import typer

from geoproc.errors import UsageError
from geoproc.fileio import require_input_file
from geoproc_cli.common import (
    CheckOpt,
    DebugOpt,
    QuietOpt,
    ReportOpt,
    command_run,
    flag,
    metrics_epilog,
    refuse_options,
    require_extension,
)

EXACT_METRICS = ("rmse", "max_abs_error", "bias", "error_points", "declared_laplacian", "declared_mean_value_gap",
                 "declared_flux_gap")
"""The errors against the boundary function as the exact solution, reported only with ``--exact``."""

METRICS = EXACT_METRICS + (
    "segments", "loops", "neumann_segments", "domain_area", "grid_width", "grid_height", "grid_points_inside",
    "pixel_size", "grid_left", "grid_top", "walks", "kernels_used", "fit_points", "fit_walks", "fit_seconds",
    "fit_steps", "control_variate_variance_ratio", "control_variate_used",
    "refine_seconds", "refine_steps", "refine_iterations", "residual_seconds", "residual_steps", "total_walks",
    "total_steps", "steps_per_second", "residual_steps_per_second", "mean_steps_per_walk",
    "mean_standard_error", "rms_standard_error",
)
"""Every metric ``wos-solve`` can report (which ones a run reports depends on its method and options)."""


HARMONIC_NOTE = 1e-4
"""A --exact function whose declared_laplacian or declared_mean_value_gap is above this gets a note
(harmonic ones read a few 1e-6 at most, the ones that were not 1e-3 and more, on the demo domains and
a disk with a small hole)."""

FLUX_NOTE = 0.1
"""A --exact function whose declared_flux_gap is above this gets a note: looser than
HARMONIC_NOTE, since Neumann data given for a smooth curve meets the normals of the
polyline that stands for it only to the polyline's angles (a few hundredths)."""

FLUX_CHANGE_LIMIT = 1e300
"""Neumann data whose largest magnitude times the domain's bounding-box diagonal
exceeds this are refused before the walks: the solution changes by about that
much, far beyond the EXR's float32 range, and the walks' sums overflow on the way
(data that would fit a double but not the EXR are refused when written)."""

EPSILON_NOTE = 0.01
"""An --epsilon above this fraction of the domain's bounding-box diagonal gets a note: on
a 2 mm square at the default 1e-3 every walk stopped where it started."""

FIT_METRICS = ("kernels_used", "fit_points", "fit_walks", "fit_seconds", "fit_steps", "control_variate_variance_ratio",
               "control_variate_used")
"""Reported only with a control variate (every method but naive)."""
REFINE_METRICS = ("refine_seconds", "refine_steps", "refine_iterations")
"""Reported only by npass."""


METRIC_UNITS = {
    "rmse, max_abs_error, bias, mean_standard_error, rms_standard_error": "in the solution's units",
    "declared_laplacian, declared_mean_value_gap, declared_flux_gap": "dimensionless, over the declared function's "
    "range (0 or a few 1e-6 when it is harmonic; the flux a few hundredths or more where the Neumann segments are "
    "a polyline standing for a curve, 0.19 on a 24-gon; a note above 1e-4, 0.1 for the flux)",
    "pixel_size, grid_left, grid_top, domain_area": "in the domain's length unit (area its square)",
    "control_variate_variance_ratio": "the walks' variance with the fitted control variate over plain walks', at "
    "the fit points (above 1: control_variate_used is false and the residual pass ran plain walks)",
}
"""Units of the metrics whose names do not tell, for ``--help``."""


def _metric_needs(exact: bool, method: str) -> dict[str, tuple[str, ...]]:
    """For each option not given, the metrics only it reports (a --check on one is refused at once)."""
    needs: dict[str, tuple[str, ...]] = {} if exact else {"--exact": EXACT_METRICS}
    if method == "naive":
        needs["a control variate (--method cv-green, cv-angle or npass)"] = FIT_METRICS
    if method != "npass":
        needs["--method npass"] = REFINE_METRICS
    return needs


class Method(StrEnum):
    naive = "naive"
    cv_green = "cv-green"
    cv_angle = "cv-angle"
    npass = "npass"


def wos_solve(
    ctx: typer.Context,
    domain: Annotated[str, typer.Argument(
        help="Domain: a JSON file {\"loops\": [[[x, y], ...], ...], \"neumann\": [loop indices or "
             "[loop, segment] pairs], \"values\": [[per-vertex values], ...]}, or a binary mask "
             "image (any format OpenImageIO reads; foreground = first channel other than alpha, times alpha, "
             "> 0.5, traced to "
             "polylines in pixel units, y up); - reads the JSON from stdin.", metavar="DOMAIN", show_default=False)],
    output: Annotated[str, typer.Option("--output", "-o", help="Solution image: one-channel float "
                                        "EXR over the domain's bounding box, NaN outside (a file ending in .exr, "
                                        "or a device such as /dev/null; not -).",
                                        metavar="U.exr", show_default=False)],
    boundary: Annotated[str | None, typer.Option(
        "--boundary", help="Dirichlet data as an expression in x and y: numbers, + - * / **, "
        "parentheses, sin cos tan exp log sqrt abs atan2 sinh cosh, pi, e. Default: the "
        "JSON's per-vertex 'values' (given, it replaces them, with a note).", metavar="'EXPR'",
        show_default=False)] = None,
    neumann: Annotated[str | None, typer.Option(
        "--neumann", help="Flux du/dn (outward normal) on the segments the JSON marks Neumann, "
        "as an expression in x, y and the segment's outward unit normal nx, ny (the flux of a known "
        "u is its gradient dotted with (nx, ny): 'nx' for u = x); marked segments without it have "
        "zero flux.", metavar="'EXPR'",
        show_default=False)] = None,
    method: Annotated[Method, typer.Option(
        "--method", "-m", help="naive: plain walks; cv-green / cv-angle: fit a control variate of "
        "Green / segment-angle kernels, then walk the residual; npass: cv-green refined by Adam "
        "on fresh walk batches. cv-angle takes Dirichlet-only domains.")] = Method.naive,
    walks: Annotated[int, typer.Option("--walks", help="Walks per grid point (1 to 10^7).", min=1,
                                       max=10**7)] = 128,
    grid: Annotated[int, typer.Option("--grid", help="Pixels along the bounding box's longer "
                                      "side (1 to 8192); the shorter side gets as many as cover it.",
                                      min=1, max=8192)] = 256,
    epsilon: Annotated[float, typer.Option("--epsilon", help="Stopping distance to the Dirichlet "
                                           "boundary, > 0, in domain length units (the default suits a domain "
                                           "about 1 across; a note says when it is over 1 % of the "
                                           "bounding-box diagonal).")] = 1e-3,
    kernels: Annotated[int, typer.Option("--kernels", help="Control-variate kernels (1 to 10000; cv-angle "
                                         "uses at most one per boundary segment).",
                                         min=1, max=10000)] = 80,
    fit_walks: Annotated[int, typer.Option("--fit-walks", help="Walks per fit point (1 to 10^7).",
                                           min=1, max=10**7)] = 128,
    fit_points: Annotated[int | None, typer.Option(
        "--fit-points", help="Fit points spread in the domain, 1 to 10^6, at most the grid points farther than "
        "2 x epsilon from the boundary [default: 8 x the kernels used].", min=1, max=10**6,
        show_default=False)] = None,
    ridge: Annotated[float | None, typer.Option(
        "--ridge", help="Ridge weight of the fit, >= 0, on kernel columns centred and scaled to unit standard "
        "deviation [default: 1 for cv-green and npass, 0.1 for cv-angle].", show_default=False)] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed, 0 to 2^64 - 1; same seed, same output bytes.",
                                      min=0, max=2**64 - 1)] = 0,
    exact: Annotated[bool, flag(
        "--exact", help="Declare --boundary harmonic, hence the exact solution: report rmse, "
        "max_abs_error and bias over grid points inside and farther than 2 epsilon from the "
        "boundary.")] = False,
    error_image: Annotated[str | None, typer.Option(
        "--error-image", help="PNG of the absolute error (needs --exact; - for stdout).", metavar="E.png",
        show_default=False)] = None,
    image: Annotated[str | None, typer.Option("--image", help="Colormapped PNG of the solution "
                                              "with contour lines (- for stdout).", metavar="U.png",
                                              show_default=False)] = None,
    stderr_image: Annotated[str | None, typer.Option(
        "--stderr-image", help="Standard error of each pixel's estimate (the walks' sample standard "
        "deviation over sqrt(--walks), in the solution's units) as a one-channel float EXR on the "
        "solution's grid, NaN outside; needs --walks 2 or more.", metavar="SE.exr",
        show_default=False)] = None,
    report: ReportOpt = None,
    check: CheckOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Solve the Laplace equation on a 2D domain by Walk on Spheres (Dirichlet) or Walk on
    Stars (mixed Dirichlet/Neumann), optionally with a harmonic control variate.

    The report holds walks, total_steps, steps_per_second, residual_seconds and,
    with a control variate, fit_seconds (and rmse, max_abs_error, bias with --exact); all are
    metrics for --check, e.g. --check 'rmse<=0.01'.
    """
    fitted = method != Method.naive  # the control-variate fit's options (refused with naive)
    params = {"domain": domain, "output": output, "image": image, "error_image": error_image,
              "stderr_image": stderr_image,
              "boundary": boundary, "neumann": neumann, "method": method.value,
              "walks": walks, "grid": grid, "epsilon": epsilon, "kernels": kernels if fitted else None,
              "fit_walks": fit_walks if fitted else None, "fit_points": fit_points if fitted else None,
              "ridge": ridge if fitted else None, "seed": seed, "exact": exact}
    with command_run("wos-solve", params, report=report, checks=check, quiet=quiet, debug=debug,
                     outputs=[output, image, error_image, stderr_image], inputs=[domain], metrics=METRICS,
                     needs=_metric_needs(exact, method)) as run:
        require_extension(output, ".exr", "-o")
        if method == Method.naive:
            refuse_options(ctx, ("kernels", "fit_walks", "fit_points", "ridge"),
                           "only with a control variate (--method cv-green, cv-angle or npass)")
        if image:
            require_extension(image, ".png", "--image", stdout_ok=True)
        if stderr_image:
            require_extension(stderr_image, ".exr", "--stderr-image")
            if walks < 2:
                raise UsageError("--stderr-image needs --walks 2 or more (one walk per point has no "
                                 "spread to measure)")
        if error_image:
            require_extension(error_image, ".png", "--error-image", stdout_ok=True)
            if not exact:
                raise UsageError("--error-image needs --exact (the error is against the exact solution)")
        from geoproc.wos.expression import parse_expression  # plain Python: no numba yet

        g = parse_expression(boundary, "--boundary") if boundary is not None else None
        h = parse_expression(neumann, "--neumann", normals=True) if neumann is not None else None
        if domain != "-":  # a missing domain is refused before numba and matplotlib load
            require_input_file(domain, "domain file")
        from geoproc.wos import load_domain, solve_laplace
        from geoproc.wos.images import EXR_MAX, exr_bytes, float32_steps, png_bytes
        from geoproc.wos.solve import FIT_POINTS_PER_KERNEL, default_ridge, suggested_epsilon

        if fitted and ridge is None:  # the report names the weight used
            run.params["ridge"] = default_ridge(method.value)

        with run.timer("load"):
            dom = run.read_input(domain, load_domain, "domain file")
        if dom.traced:
            run.note(f"{domain}: traced {len(dom.loops)} loop(s), {dom.n_segments} segments, "
                     f"area {dom.area:.6g} px^2")
        if g is not None and dom.values is not None:
            run.note(f"{domain}: --boundary replaces the domain's own 'values' (they are not used)")
        # Dirichlet data beyond what the EXR holds, which the solution reaches near there, is
        # refused before the walks (npass had overflowed on it and blamed data past 1e307)
        from geoproc.wos.problem import dirichlet_data_bound

        data = "--boundary reaches" if g is not None else "the domain's values reach"
        big = dirichlet_data_bound(dom, g)
        if big > EXR_MAX:
            raise UsageError(f"{domain}: {data} {big:.3g} on the Dirichlet boundary, beyond the float32 "
                             f"range of the EXR output ({EXR_MAX:.3g}); rescale the boundary data")
        lo, hi = dom.bbox
        diag = float(np.linalg.norm(hi - lo))
        # a flux that large makes the solution's change over the domain (about flux x size) overflow
        # the walks' doubles long before it could fit the EXR: npass had overflowed on 1e160 and
        # blamed data past 1e307, cv-green had warned from its fit
        from geoproc.wos.problem import neumann_data_bound

        big = neumann_data_bound(dom, h)
        if big * diag > FLUX_CHANGE_LIMIT:
            raise UsageError(f"{domain}: --neumann reaches {big:.3g} on the Neumann boundary, over a domain "
                             f"{diag:.3g} across: the solution would be far beyond the float32 range of the "
                             f"EXR output ({EXR_MAX:.3g}); rescale the boundary data")
        if epsilon > EPSILON_NOTE * diag:
            run.note(f"--epsilon {epsilon:g} is {epsilon / diag:.2g} of the domain's bounding-box diagonal "
                     f"({diag:.3g}): walks stop that far from the boundary and score the closest boundary "
                     "point, a bias the standard error does not show; --epsilon is in the domain's length "
                     f"units (try {suggested_epsilon(diag):.2g}, as 0.001 is to a unit square)")
        with run.timer("solve"), run.progress("walking", 1.0) as update:
            res = solve_laplace(dom, g, flux=h, method=method.value, walks=walks, grid=grid,
                                eps=epsilon, kernels=kernels, fit_walks=fit_walks,
                                fit_points_n=fit_points, ridge=ridge, seed=seed, exact=exact,
                                progress=update)
        run.metrics.update(res.metrics)
        used = res.metrics.get("kernels_used")
        if used is not None and used > kernels:  # cv-angle: one or more on every loop
            run.note(f"{used} kernels used, not {kernels}: cv-angle shares them among the "
                     f"{len(dom.loops)} boundary loops by length, each loop's share rounded and at least one")
        if fitted and fit_points is None:  # the default the run used (8 x kernels, at most the grid's)
            run.params["fit_points"] = res.metrics.get("fit_points")
        if used is not None and used < kernels:
            capped = method == Method.cv_angle and used == dom.n_segments
            why = "cv-angle puts at most one on each boundary segment" if capped else "the kernel placement gave fewer"
            run.note(f"{used} kernels used, not {kernels}: {why}")
        from geoproc.wos.problem import MAX_STEPS

        # a walk needs a few dozen steps to reach a stopping distance of 1e-16 of a unit domain;
        # below what rounding resolves, walks stall at the boundary and run to the cap
        if res.metrics["mean_steps_per_walk"] > MAX_STEPS / 10:
            run.note(f"the walks took {res.metrics['mean_steps_per_walk']:.0f} steps on average; a walk that "
                     f"reaches {MAX_STEPS} steps stops and scores the closest boundary point, which biases "
                     "the estimate. Long Neumann corridors take that many steps, and so does an --epsilon "
                     f"finer than the coordinates' rounding ({epsilon:g} here), where walks stall at the boundary")
        wanted = fit_points if fit_points is not None else FIT_POINTS_PER_KERNEL * (used or 0)
        if fitted and res.metrics.get("fit_points", wanted) < wanted:
            where = ("every grid point farther than 2 x epsilon from the boundary" if res.scored.any() else
                     "every grid point, none being farther than 2 x epsilon from the boundary")
            run.note(f"{res.metrics['fit_points']} fit points used, not {wanted}"
                     f"{'' if fit_points is not None else f' ({FIT_POINTS_PER_KERNEL} x the kernels used)'}: "
                     f"{where} (raise --grid for more)")
        if fitted and not res.metrics["control_variate_used"]:
            run.note(f"the control variate fitted at {res.metrics['fit_points']} points gave the walks "
                     f"{res.metrics['control_variate_variance_ratio']:.3g} times the variance of plain walks there: "
                     "the residual pass ran plain walks (the result is the naive method's; more fit points, "
                     "from a finer --grid or --fit-points, more --fit-walks or fewer --kernels make a better fit"
                     + (", and so does a --ridge above 0)" if ridge == 0 else ")"))
        elif fitted and ridge == 0 and used and res.metrics.get("fit_points", 0) <= used:
            run.note(f"--ridge 0 with {res.metrics.get('fit_points', 0)} fit points for {used} kernels: the fit is "
                     "the minimum-norm one through the fit walks' noise, whose large coefficients the control "
                     "variate adds back (a ridge > 0, or more fit points, keeps them small)")
        if exact:
            _note_declared_checks(run, res.metrics, neumann is not None)
        gs = res.grid
        extent = (gs.x0, gs.x0 + gs.nx * gs.h, gs.y1 - gs.ny * gs.h, gs.y1)
        # where the image lies: pixel (row, col) is centred at (grid_left + (col + 0.5) pixel_size,
        # grid_top - (row + 0.5) pixel_size), in the file itself as in the report
        placed = {f"geoproc:{k}": res.metrics[k] for k in ("grid_left", "grid_top", "pixel_size")}
        with run.timer("write"):
            try:
                encoded = exr_bytes(res.U, attributes=placed)
            except UsageError as exc:  # boundary data too large for float32: name the domain
                raise UsageError(f"{domain}: {exc}") from None
            run.write_bytes(output, encoded)
            if stderr_image:
                # (bounded by the solution's range, which fits; below float32's range it reads 0)
                run.write_bytes(stderr_image, exr_bytes(res.stderr, solution=False, attributes=placed))
            fin = res.U[np.isfinite(res.U)]
            lo, hi = (float(fin.min()), float(fin.max())) if fin.size else (0.0, 0.0)
            steps = float32_steps(lo, hi)
            # constant Dirichlet data and no flux: the solution is that constant, and any spread is the
            # walks' rounding (1e-14 around 1 with a control variate; the note had advised subtracting
            # a constant)
            from geoproc.wos.expression import is_zero
            from geoproc.wos.problem import constant_dirichlet_data

            constant = (h is None or is_zero(h)) and constant_dirichlet_data(dom, g)
            if 0 < steps < 1000 and not constant:
                levels = "less than one step" if steps < 1 else f"only {steps:.0f} steps"
                fix = ("multiply the boundary data by a constant" if max(abs(lo), abs(hi)) < np.finfo(np.float32).tiny
                       else "subtract a constant from the boundary data (a value it takes on the domain)")
                run.note(f"the solution varies by {hi - lo:.3g} around {max(abs(lo), abs(hi)):.3g}, which the "
                         f"float32 EXR resolves in {levels}; {fix} to keep its digits")
            name = os.path.basename(domain)
            if image:
                run.write_bytes(image, png_bytes(res.U, extent, f"{name}: {method.value}, "
                                                 f"{walks} walks/point"))
            if error_image:
                err = np.abs(res.U - res.exact)
                err[~res.scored] = np.nan
                run.write_bytes(error_image, png_bytes(
                    err, extent, f"{name}: |error|, {method.value}, rmse "
                    f"{res.metrics['rmse']:.3g}", cmap="magma", contours=0, label="|u - exact|"))


def _measured(value) -> bool:
    """Whether a check's value was measured (not None, not NaN)."""
    return value is not None and value == value


def _note_declared_checks(run, metrics: dict, neumann_given: bool) -> None:
    """--exact: the notes on the declared function's checks (``metrics``:
    declared_laplacian, declared_mean_value_gap, declared_flux_gap): where it
    is not harmonic or not the Neumann data's solution, rmse measures the
    difference to it; where rounding hides what a check looks for, it could
    not be checked."""
    lap, gap, flux_gap = (metrics.get(k) for k in
                          ("declared_laplacian", "declared_mean_value_gap", "declared_flux_gap"))
    signs = ([f"its Laplacian reaches {lap:.3g} of its range per squared diagonal"]
             if _measured(lap) and lap > HARMONIC_NOTE else [])
    if _measured(gap) and gap > HARMONIC_NOTE:  # also a singular point inside, which the stencils can miss
        signs.append("its mean over circles inside the domain differs from its value at their centre by "
                     + (f"{gap:.3g} of its range" if np.isfinite(gap) else "an infinite amount"))
    if metrics.get("neumann_segments") and not _measured(flux_gap):
        run.note("--exact: cannot check --boundary against the Neumann data: rounding its values hides "
                 "the difference at every sample (declared_flux_gap is null); subtracting a constant from "
                 "--boundary, or moving the domain nearer the origin, lets it check")
    if _measured(flux_gap) and flux_gap > FLUX_NOTE:
        given = "--neumann" if neumann_given else "the zero flux of Neumann segments without --neumann"
        run.note(f"--exact: the normal derivative of --boundary on the Neumann segments differs from {given} "
                 + (f"by {flux_gap:.3g} of its range per diagonal" if np.isfinite(flux_gap) else "(not finite)")
                 + ", so it does not solve the mixed problem the walks estimate, and rmse measures the "
                 "difference to it")
    if signs:
        run.note(f"--exact: --boundary is not harmonic ({'; '.join(signs)}), so it is not the solution the "
                 "walks estimate, and rmse measures the difference to it")
    elif not (_measured(lap) or _measured(gap)):  # both null: rounding hides what they look for
        run.note("--exact: cannot check that --boundary is harmonic: its values are so large for their range "
                 "over the domain that rounding them hides what the checks look for (declared_laplacian and "
                 "declared_mean_value_gap are null); subtracting a constant from --boundary, or moving the domain "
                 "nearer the origin with --boundary written for it, lets them check")


def register(app: typer.Typer) -> None:
    """Add ``wos-solve`` to the application."""
    app.command("wos-solve", epilog=metrics_epilog(METRICS, units=METRIC_UNITS))(wos_solve)
