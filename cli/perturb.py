"""``geoproc perturb``: reproducible noise on a mesh, point cloud or animation."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import typer

from geoproc.animation import Animation, is_animation_path
from geoproc.errors import InputError, UsageError, frame_error
from geoproc.mesh.validate import require_triangle_frames, require_triangle_mesh
from geoproc.perturb import DIRECTIONS, NoiseSpec, noise_scale, perturb_positions
from geoproc_cli.common import (
    LOAD_METRICS,
    CheckOpt,
    DebugOpt,
    NoCleanOpt,
    QuietOpt,
    ReportOpt,
    choices_metavar,
    command_run,
    frame_folder_outputs,
    input_kind_needs,
    metrics_epilog,
    refuse_options,
    require_animation_output,
    require_ply_output,
)

METRICS = LOAD_METRICS + (
    "vertices", "faces", "frames", "noise_scale", "rms_displacement", "outlier_vertices",
)
"""Every metric ``perturb`` can report (``frames`` for animations)."""


METRIC_UNITS = {
    "noise_scale": "the mean edge length (mean nearest-neighbour distance for a cloud): the unit of --noise",
    "rms_displacement": "in the input's length unit",
}
"""Units of the metrics whose names do not tell, for ``--help``."""


def perturb(
    ctx: typer.Context,
    input: Annotated[str, typer.Argument(help="Mesh or point cloud (.obj, .ply, .off, .stl, - for stdin), "
                                         "or an animation (.npz with 'vertices' (frames, n, 3) and 'faces', "
                                         "or a folder of frame meshes).", metavar="INPUT")],
    output: Annotated[str, typer.Option("--output", "-o", help="Output file: a mesh (.ply keeps the "
                                        "'outlier' property; - is binary PLY on stdout); for an animation, "
                                        ".npz or a folder (a name ending in '/', or an existing folder) "
                                        "of binary PLY frames frame_0000.ply, ... (made if needed; "
                                        "any other frame_N.ply file there, from an earlier run, is removed).",
                                        metavar="OUT")],
    seed: Annotated[int, typer.Option("--seed", help="Random seed, 0 to 2^64 - 1: the same seed gives the same bytes.",
                                      min=0, max=2**64 - 1)],
    noise: Annotated[float, typer.Option("--noise", help="Gaussian noise standard deviation, >= 0, in mean edge "
                                         "lengths (mean nearest-neighbour distance for a point cloud).",
                                         metavar="SIGMA")] = 0.3,
    direction: Annotated[str, typer.Option("--direction", help="normal: along vertex normals of the "
                                           "consistently oriented faces (the benchmark protocol; a point "
                                           "cloud's are the least-variance directions of its 16 nearest "
                                           "neighbours); random: along "
                                           "random unit directions (sigma/sqrt(3) per axis).",
                                           metavar=choices_metavar(DIRECTIONS))]
    = "normal",
    impulsive: Annotated[float, typer.Option("--impulsive", help="Apply the Gaussian noise to only this "
                                             "fraction of the vertices, chosen at random (impulsive noise), 0 "
                                             "to 1; 1, the default, moves every vertex, 0 none.",
                                             metavar="FRACTION")] = 1.0,
    outliers: Annotated[float, typer.Option("--outliers", help="Fraction of vertices moved as outliers, "
                                            "0 to 1 (flagged in the per-vertex 'outlier' property, added to "
                                            "any flags the input carries).",
                                            metavar="FRACTION")] = 0.0,
    outlier_range: Annotated[float, typer.Option("--outlier-range", help="Outliers move uniformly within "
                                                 "a ball of this many (> 0) bounding-box diagonals (of the vertices "
                                                 "the faces use; of every point of a point cloud) around their "
                                                 "noisy position.",
                                                 metavar="R")] = 0.02,
    no_clean: NoCleanOpt = False,
    report: ReportOpt = None,
    check: CheckOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Add reproducible noise: Gaussian along normals by default, impulsive noise on a
    fraction of the vertices, and outliers flagged in an 'outlier' property.

    Example: geoproc perturb bunny.off --noise 0.3 --seed 1 -o noisy.ply
    """
    params = {"input": input, "output": output, "noise": noise, "direction": direction, "impulsive": impulsive,
              "outliers": outliers, "outlier_range": outlier_range, "seed": seed, "clean": not no_clean}
    animation = input != "-" and is_animation_path(input)
    if animation:
        params["clean"] = None  # frames are read as stored
    if noise == 0:
        params["direction"] = params["impulsive"] = None  # no noise to direct
    if not outliers > 0:
        params["outlier_range"] = None
    needs = input_kind_needs(animation, ("frames",))
    files, folders = frame_folder_outputs(output, animation)
    with command_run("perturb", params, report=report, checks=check, quiet=quiet, debug=debug,
                     outputs=files, folders=folders, inputs=[input], metrics=METRICS, needs=needs) as run:
        if noise < 0:
            raise UsageError(f"--noise {noise}: must be >= 0")
        if direction not in DIRECTIONS:
            raise UsageError(f"--direction {direction}: use normal or random")
        for name, v in (("--impulsive", impulsive), ("--outliers", outliers)):
            if not 0.0 <= v <= 1.0:
                raise UsageError(f"{name} {v}: must be a fraction in [0, 1]")
        if noise == 0:
            refuse_options(ctx, ("direction", "impulsive"), "not used with --noise 0")
        if outliers == 0:
            refuse_options(ctx, ("outlier_range",), "only with --outliers FRACTION > 0")
        elif not animation:  # (an animation's output is checked below)
            require_ply_output(output, "the outliers are flagged in a vertex property")
        if not outlier_range > 0:  # reached only with --outliers > 0 (refused above otherwise)
            raise UsageError(f"--outlier-range {outlier_range}: must be > 0 (0 would move no outlier)")
        spec = NoiseSpec(sigma=noise, direction=direction, impulsive=impulsive, outliers=outliers,
                         outlier_range=outlier_range)
        rng = np.random.default_rng(seed)
        if animation:
            require_animation_output(output)
            refuse_options(ctx, ("no_clean",), "not used for an animation (frames are read as stored)")
            anim = run.load_animation(input, output)
            if len(anim.F):  # a moving point cloud has no faces; its frames are checked as clouds below
                require_triangle_frames(anim.V, anim.F, anim.path, anim.frame_files)  # normals and the edge-length unit
            _note_fractions_of_none(run, int(anim.V.shape[1]), impulsive, outliers)
            with run.timer("compute"):
                frames, flags, scales = [], [], []
                for t in range(anim.n_frames):
                    try:  # sigma in each frame's own length unit
                        scales.append(noise_scale(anim.V[t], anim.F))
                        Vt, ot = perturb_positions(anim.V[t], anim.F, spec, rng, input, scale=scales[-1])
                    except InputError as exc:  # say which frame
                        raise frame_error(exc.path, t, exc.problem, anim.frame_files) from None
                    frames.append(Vt)
                    flags.append(ot)
                fields = dict(anim.fields)
                V = np.stack(frames)
                run.refresh_normals(V, anim.F, fields)
                flag = _merged_flags(run, np.stack(flags), fields, anim.V.shape[:2], anim.path, outliers > 0,
                                     anim.frame_files)
                out = Animation(V, anim.F, fields, output)
            run.metrics.update({"frames": anim.n_frames, "vertices": int(anim.V.shape[1]),
                                "faces": len(anim.F),
                                "noise_scale": float(np.mean(scales)),
                                "rms_displacement": _rms(V - anim.V),
                                "outlier_vertices": int(flag.sum())})
            run.write_animation(output, out)
            return
        mesh = run.load_mesh(input, clean=not no_clean, mesh_output=output)
        if not mesh.is_point_cloud:
            require_triangle_mesh(mesh)  # normals, and the edge-length unit, need a face of some area
            if no_clean and (noise > 0 or outliers > 0):
                run.note_kept_seams(mesh, mesh.log.path or input)
        _note_fractions_of_none(run, len(mesh.V), impulsive, outliers)
        with run.timer("compute"):
            scale = noise_scale(mesh.V, mesh.F)
            V, flag = perturb_positions(mesh.V, mesh.F, spec, rng, mesh.log.path, scale)
        out = mesh.copy()
        out.V = V
        run.refresh_normals(out.V, out.F, out.vertex_fields)
        flag = _merged_flags(run, flag, out.vertex_fields, (len(V),), mesh.log.path or input, outliers > 0)
        run.metrics.update({"vertices": len(V), "faces": len(mesh.F),
                            "noise_scale": scale,
                            "rms_displacement": _rms(V - mesh.V),
                            "outlier_vertices": int(flag.sum())})
        run.write_mesh(output, out)


def _rms(D: np.ndarray) -> float:
    """Root mean square length of the (..., 3) displacements."""
    return float(np.sqrt(np.mean(np.sum(D**2, axis=-1)))) if D.size else 0.0


def _merged_flags(run, new: np.ndarray, fields: dict, shape: tuple, path: str, added: bool,
                  frame_files: list[str] | None = None) -> np.ndarray:
    """The ``outlier`` flags after this run: those the input already carried
    (an earlier perturb) joined with the ``new`` ones (1.0 where moved as an
    outlier now); ``fields["outlier"]`` is set when outliers were ``added``.
    An input property with values other than 0 and 1 (interpolated by
    ``morse-simplify --barycentric``, say) is read as flags above 0.5, with a
    note. Returns the (bool) flags, of ``shape``."""
    flags = new > 0.5
    if "outlier" in fields:
        flags |= run.outlier_flags(fields["outlier"], shape, path, frame_files, rewritten=added)
    if added:
        fields["outlier"] = flags.astype(np.float64)
    return flags


def register(app: typer.Typer) -> None:
    """Add ``perturb`` to the application."""
    app.command("perturb", epilog=metrics_epilog(METRICS, units=METRIC_UNITS))(perturb)


def _note_fractions_of_none(run, n: int, impulsive: float, outliers: float) -> None:
    """A note when a positive --impulsive or --outliers fraction of n vertices rounds to none,
    and for --impulsive 0 (which had meant every vertex)."""
    if impulsive == 0:
        run.note("--impulsive 0: the Gaussian noise moves no vertex (1, the default, moves every one)")
    for option, fraction, what in (("--impulsive", impulsive, "the noise moves no vertex"),
                                   ("--outliers", outliers, "no outlier is added")):
        if fraction > 0 and round(fraction * n) == 0:
            run.note(f"{option} {fraction:g} of {n} vertices rounds to none: {what}")
