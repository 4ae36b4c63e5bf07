"""``geoproc denoise``: feature-preserving mesh denoising, point-cloud outlier
removal, and animation denoising."""

from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Annotated, NamedTuple

import numpy as np
import typer

from geoproc.animation import Animation, is_animation_path
from geoproc.denoise import COHERENCE, DEFAULT_METHOD, METHODS
from geoproc.errors import InputError, UsageError, shown_number
from geoproc.mesh import Mesh, load_mesh
from geoproc.mesh.validate import require_triangle_frames, require_triangle_mesh
from geoproc.perturb import outlier_flags
from geoproc_cli.common import (
    LOAD_METRICS,
    CheckOpt,
    DebugOpt,
    NoCleanOpt,
    QuietOpt,
    ReportOpt,
    choices_metavar,
    command_run,
    flag,
    frame_folder_outputs,
    metrics_epilog,
    options_given,
    refuse_options,
    require_animation_output,
    require_memory,
    require_ply_output,
)

REFERENCE_METRICS = (
    "mean_normal_angle_deg", "max_normal_angle_deg", "flipped_faces", "hausdorff", "vertex_rmse",
    "input_mean_normal_angle_deg", "input_flipped_faces", "new_flipped_faces",
)
"""The errors against the clean mesh or animation, reported only with ``--reference``."""

METRIC_UNITS = {
    "hausdorff": "two-sided, over the clean mesh's bounding-box diagonal",
    "vertex_rmse": "in the clean mesh's mean edge lengths",
    "flipped_faces": "faces more than 90 degrees from the clean mesh",
    "sigma_s": "in centroid spacings (sigma_s_length in length units)",
    "sigma_r": "as the distance |n_i - n_j| between unit normals (0 to 2)",
    "noise_roughness": "in mean edge lengths (the median jump of the vertices' heights over their rings)",
    "feature_tau": "in each vertex's mean edge length",
    "threshold": "(--outliers) in median point spacings",
    "mean_refinement_shift": "(--outliers) in the cloud's length unit",
}
"""Units of the metrics whose names do not tell, for ``--help``."""

METRICS = LOAD_METRICS + REFERENCE_METRICS + (
    # meshes: sizes, the noise and shape estimates, the parameters used, the repairs
    "vertices", "faces", "feature_faces", "noise_median_dihedral_deg", "noise_roughness", "coarseness_deg",
    "dihedral_tail_ratio", "reoriented_faces", "sliver_faces", "guidance_mix", "outer_iterations", "normal_iterations",
    "vertex_iterations", "fidelity", "sigma_r", "sigma_s", "sigma_s_length", "unfold_rounds", "folded_faces",
    "crease_repair", "crease_bisected_faces", "input_side_faces", "rpca_sparse_faces", "repeated_corner_faces",
    "scale_groups",
    # feature detection
    "feature_method", "feature_angle_deg", "feature_lambda", "feature_tau", "feature_vertices",
    "feature_admm_iterations",
    # --outliers (clouds and moving clouds); precision, recall and f1 need an 'outlier' property
    "points", "detected_outliers", "threshold", "true_outliers", "precision", "recall", "f1",
    "mean_refinement_shift", "motion_basis",
    # --dynamic
    "frames", "coherence", "rpca_iterations", "rpca_converged", "low_rank", "turn_limited_vertices",
)
"""Every metric ``denoise`` can report (which ones a run reports depends on its mode and options)."""
TEXT_METRICS = ("feature_method", "coherence")
"""The metrics among them that are text (names), which ``--check`` cannot compare."""
FEATURE_RULES = ("dihedral", "l1")
"""The values of --features."""


def denoise(
    ctx: typer.Context,
    input: Annotated[str, typer.Argument(help="Noisy mesh (.obj, .ply, .off, .stl, - for stdin); a point "
                                         "cloud with --outliers; an animation (.npz or folder of frames) "
                                         "with --dynamic.", metavar="INPUT")],
    output: Annotated[str, typer.Option("--output", "-o", help="Output: a mesh (.ply keeps the per-face "
                                        "'feature' property; - is binary PLY on stdout), the inlier cloud "
                                        "with --outliers; for an animation (--dynamic, or --outliers on "
                                        "one), .npz or a folder (a name ending in '/', or an existing "
                                        "folder) of binary PLY frames frame_0000.ply, ... (made if needed; "
                                        "any other frame_N.ply file there, from an earlier run, is removed).",
                                        metavar="OUT")],
    method: Annotated[str, typer.Option("--method", "-m", help=f"Normal filter: {', '.join(METHODS)}.",
                                        metavar=choices_metavar(METHODS))]
    = DEFAULT_METHOD,
    reference: Annotated[str | None, typer.Option("--reference", help="Clean version with the same "
                                                  "faces in the same order (mesh, or .npz or folder of frames "
                                                  "with --dynamic; "
                                                  "its vertices may be numbered otherwise, as in an STL "
                                                  "copy): report the error metrics; - reads a mesh from "
                                                  "stdin.", metavar="CLEAN")] = None,
    rounds: Annotated[int | None, typer.Option("--rounds", help="Rounds of normal filtering + vertex "
                                               "update, 0 to 1000 (default: from the estimated noise level).",
                                               min=0, max=1000, show_default=False)] = None,
    normal_iterations: Annotated[int | None, typer.Option("--normal-iterations", help="Filter passes per "
                                                          "round, 0 to 10000 (default: from the noise level).",
                                                          min=0, max=10000, show_default=False)] = None,
    vertex_iterations: Annotated[int, typer.Option("--vertex-iterations", help="Vertex-update sweeps "
                                                   "per round, 0 to 10000.", min=0, max=10000)] = 10,
    fidelity: Annotated[float, typer.Option("--fidelity", help="Data term of the vertex update: every "
                                            "sweep adds to its step towards the filtered normals this "
                                            "fraction of the way back to the vertex's input position, 0 to 1 "
                                            "(0: the plain fit; 1: each sweep is one fit step from the "
                                            "input).")] = 0.005,
    sigma_r: Annotated[float | None, typer.Option("--sigma-r", help="Range kernel width on normal "
                                                  "differences, as the chord length between unit normals "
                                                  "(> 0; 0.3 is about 17 degrees; default: from the noise level).",
                                                  show_default=False)] = None,
    sigma_s: Annotated[float | None, typer.Option("--sigma-s", help="Spatial kernel width, > 0, in mean "
                                                  "distances between adjacent face centroids (default: from "
                                                  "the mesh, 1, up to 2 on coarse meshes without creases).",
                                                  show_default=False)] = None,
    guidance_mix: Annotated[float | None, typer.Option("--guidance-mix", help="--method guided: each "
                                                       "pass's guidance is the patch guidance blended with the "
                                                       "normals themselves by this weight, 0 to 1 (0: the patch "
                                                       "guidance alone, as Zhang et al.; 1: the normals, as the "
                                                       "bilateral filter's range kernel; default: from the noise "
                                                       "level and the mesh).", show_default=False)] = None,
    crease_repair: Annotated[bool | None, flag("--crease-repair/--no-crease-repair", help="Before the last fit, "
                                               "turn the targets of faces the fit squashed against a crease into "
                                               "bisectors and fit again (on finely meshed surfaces after narrow "
                                               "guided passes and a second fit; default: with --method guided at "
                                               "strong noise, roughness >= 0.18). --method guided "
                                               "--guidance-mix 0 --no-crease-repair is Zhang et al.'s filter as "
                                               "published.", show_default=False)] = None,
    pin_boundary: Annotated[bool, flag("--pin-boundary", help="Keep boundary vertices fixed.")]
    = False,
    features: Annotated[str, typer.Option("--features", help="How the per-face 'feature' output is found: "
                                          "l1 (support of the l1-sparse normal Laplacian n.(Lv) of the "
                                          "result) or dihedral (filtered normals of edge neighbours more "
                                          "than --feature-angle apart).",
                                          metavar=choices_metavar(FEATURE_RULES))] = "dihedral",
    feature_tau: Annotated[float, typer.Option("--feature-tau", help="--features l1: cut on the sparse "
                                               "normal Laplacian, >= 0, in local mean edge lengths (0.12 is a "
                                               "crease of about 24 degrees).")] = 0.12,
    feature_angle: Annotated[float, typer.Option("--feature-angle", help="--features dihedral: angle in "
                                                 "degrees, 0 to 180.")] = 30.0,
    outliers: Annotated[bool, flag("--outliers", help="Point-cloud outlier removal by RPCA on "
                                           "k-nearest-neighbour matrices; for an animation (.npz or folder "
                                           "of frames), RPCA on the animation matrix (one row per point: "
                                           "its x, y, z in every frame) flags the outlying points of every "
                                           "frame.")] = False,
    k: Annotated[int, typer.Option("--k", help="Neighbourhood size for --outliers on a point cloud, in points "
                                     "(at least 4, at most the number of distinct points; near copies count "
                                     "once).")] = 16,
    threshold: Annotated[float | None, typer.Option("--threshold", help="--outliers cut on the score, >= 0, in "
                                                    "median point spacings (default max(0.5, 3 x the median "
                                                    "score), which rises with the inliers' noise; the "
                                                    "report's threshold metric gives the cut used).",
                                                    show_default=False)] = None,
    keep_all: Annotated[bool, flag("--keep-all", help="--outliers: write every point with "
                                           "'outlier_score' and 'outlier_detected' properties (a point "
                                           "cloud; an animation's output always has every point, so it is "
                                           "refused there).")] = False,
    refined: Annotated[bool, flag("--refined", help="--outliers: write the refined (denoised) "
                                          "positions instead of the input ones: the merged projections "
                                          "onto the neighbourhoods' robust planes; for an animation, the "
                                          "robust low-rank trajectories.")] = False,
    dynamic: Annotated[bool, flag("--dynamic", help="Animation denoising: every frame denoised, "
                                          "then RPCA on the (vertices x frames) matrix of normal heights over "
                                          "a smooth base keeps the temporally coherent detail (after "
                                          "Algorithm 4; --coherence normals runs Algorithm 4 as "
                                          "written).")] = False,
    coherence: Annotated[str | None, typer.Option("--coherence", help="--dynamic: what RPCA makes "
                                                  "coherent over time: heights (the vertices' normal "
                                                  "heights over a smooth base; lower error) or normals "
                                                  "(the stacked face normals, then 3 vertex-update sweeps "
                                                  "per frame: the review's Algorithm 4 as written). "
                                                  "Default: heights.", show_default=False,
                                                  metavar=choices_metavar(COHERENCE))] = None,
    no_clean: NoCleanOpt = False,
    report: ReportOpt = None,
    check: CheckOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Denoise a mesh while keeping its sharp features (bilateral, guided or RPCA-guided
    normal filtering, then the vertex update); with --outliers remove point-cloud
    outliers; with --dynamic denoise an animation.

    Examples: geoproc denoise noisy.ply -o clean.ply --reference original.ply --report r.json;
    geoproc denoise cloud.ply --outliers -o inliers.ply
    """
    from geoproc.denoise.params import DenoiseParams

    coherence_used = coherence if coherence is not None or not dynamic else COHERENCE[0]
    params = {"input": input, "output": output, "method": method, "reference": reference, "rounds": rounds,
              "normal_iterations": normal_iterations, "vertex_iterations": vertex_iterations,
              "fidelity": fidelity,
              "sigma_r": sigma_r, "sigma_s": sigma_s, "guidance_mix": guidance_mix, "crease_repair": crease_repair,
              "pin_boundary": pin_boundary,
              "features": features,
              "feature_tau": feature_tau, "feature_angle": feature_angle, "outliers": outliers,
              "k": k, "threshold": threshold, "keep_all": keep_all, "refined": refined, "dynamic": dynamic,
              "coherence": coherence_used,
              "clean": not no_clean}
    mode = denoise_mode(input, outliers, dynamic)
    params.update(_options_not_used(mode, features, method))
    animation = input != "-" and is_animation_path(input)
    # --dynamic on what is not an animation is refused in the run, before any output check could name -o
    files, folders = ([], []) if mode == DYNAMIC and not animation else \
        frame_folder_outputs(output, mode in (DYNAMIC, MOVING_CLOUD))
    with command_run("denoise", params, report=report, checks=check, quiet=quiet, debug=debug,
                     outputs=files, folders=folders, inputs=[input, reference], metrics=METRICS,
                     text_metrics=TEXT_METRICS,
                     needs=_metric_needs(Choices(mode, method, features, refined, reference))) as run:
        if method not in METHODS:
            raise UsageError(f"--method {method}: use one of {', '.join(METHODS)}")
        if outliers and dynamic:
            raise UsageError("--outliers and --dynamic cannot be combined")
        _refuse_unused_options(ctx, mode, features, method)
        if mode == CLOUD and keep_all:
            require_ply_output(output, "--keep-all marks the outliers in vertex properties "
                               "(outlier_score, outlier_detected)")
        if coherence is not None and coherence not in COHERENCE:
            raise UsageError(f"--coherence {coherence}: use one of {', '.join(COHERENCE)}")
        if threshold is not None and threshold < 0:
            raise UsageError(f"--threshold {threshold}: must be >= 0")
        for option, value in (("--sigma-r", sigma_r), ("--sigma-s", sigma_s)):
            if value is not None and value <= 0:
                raise UsageError(f"{option} {shown_number(value)}: must be > 0")
        if sigma_r is not None and not sigma_r > 1e-150:  # the range kernel divides by its square (1e-300)
            raise UsageError(f"--sigma-r {shown_number(sigma_r)} is too small: the range kernel divides by its square, "
                             "which must stay above 1e-300")
        if not 0.0 <= fidelity <= 1.0:
            raise UsageError(f"--fidelity {fidelity}: must be within [0, 1]")
        if guidance_mix is not None and not 0.0 <= guidance_mix <= 1.0:
            raise UsageError(f"--guidance-mix {shown_number(guidance_mix)}: must be within [0, 1]")
        if features not in FEATURE_RULES:
            raise UsageError(f"--features {features}: use l1 or dihedral")
        if feature_tau < 0:
            raise UsageError(f"--feature-tau {shown_number(feature_tau)}: must be >= 0")
        if not 0 <= feature_angle <= 180:
            raise UsageError(f"--feature-angle {shown_number(feature_angle)}: must be within [0, 180] degrees")
        dp = DenoiseParams(outer_iterations=rounds, normal_iterations=normal_iterations,
                           vertex_iterations=vertex_iterations, fidelity=fidelity, sigma_r=sigma_r,
                           sigma_s_scale=sigma_s, guidance_mix=guidance_mix, crease_repair=crease_repair,
                           pin_boundary=pin_boundary, features=features, feature_tau=feature_tau,
                           feature_angle_deg=feature_angle)
        if mode == DYNAMIC:
            _dynamic(run, input, output, reference, method, dp, coherence_used)
        elif mode == MOVING_CLOUD:
            _animation_outliers(run, input, output, threshold, refined)
        elif mode == CLOUD:
            _outliers(run, input, output, k, threshold, keep_all, refined, no_clean)
        else:
            given = options_given(ctx, "method", "sigma_r", "sigma_s", "guidance_mix", "normal_iterations",
                                  "vertex_iterations", "fidelity", "crease_repair")
            _mesh(run, input, output, reference, method, dp, no_clean, given)


_FILTER_OPTIONS = ("method", "rounds", "normal_iterations", "vertex_iterations", "fidelity", "sigma_r",
                   "sigma_s", "guidance_mix", "crease_repair", "pin_boundary")
MESH, CLOUD, MOVING_CLOUD, DYNAMIC = "mesh", "cloud", "moving cloud", "dynamic"
"""The four modes of ``denoise``: a single mesh, --outliers on a point cloud or
on an animation, --dynamic."""
MODE_METRICS = (
    # (what reports them, whether a run with these Choices does, the metrics)
    ("--reference", lambda c: c.reference is not None and c.mode in (MESH, DYNAMIC), REFERENCE_METRICS),
    ("--outliers", lambda c: c.mode in (CLOUD, MOVING_CLOUD),
     ("points", "detected_outliers", "threshold", "true_outliers", "precision", "recall", "f1")),
    ("--outliers --refined on a point cloud (not an animation)", lambda c: c.mode == CLOUD and c.refined,
     ("mean_refinement_shift",)),
    ("--outliers on an animation", lambda c: c.mode == MOVING_CLOUD, ("motion_basis",)),
    ("--dynamic", lambda c: c.mode == DYNAMIC,
     ("coherence", "low_rank", "rpca_converged", "turn_limited_vertices")),
    ("--dynamic, or --outliers on an animation", lambda c: c.mode in (DYNAMIC, MOVING_CLOUD),
     ("frames", "rpca_iterations")),
    # with --dynamic the schedule's values are over the frames (geoproc.denoise.dynamic:
    # frame_schedule_summary): each frame's is chosen from its own noise
    ("a mesh (not --outliers)", lambda c: c.mode in (MESH, DYNAMIC),
     ("vertices", "faces", "fidelity", "vertex_iterations", "repeated_corner_faces", "noise_roughness",
      "outer_iterations", "normal_iterations", "sigma_r", "sigma_s", "scale_groups")),
    ("--method guided (the default) on a mesh", lambda c: c.mode in (MESH, DYNAMIC) and c.method == "guided",
     ("guidance_mix",)),
    ("a single mesh (not --outliers or --dynamic)", lambda c: c.mode == MESH,
     ("feature_faces", "feature_method", "noise_median_dihedral_deg", "coarseness_deg",
      "dihedral_tail_ratio", "reoriented_faces", "sliver_faces", "sigma_s_length", "unfold_rounds",
      "folded_faces", "crease_repair", "crease_bisected_faces", "input_side_faces")),
    ("--method rpca on a single mesh", lambda c: c.mode == MESH and c.method == "rpca",
     ("rpca_sparse_faces",)),
    ("--features l1", lambda c: c.mode == MESH and c.features == "l1",
     ("feature_lambda", "feature_tau", "feature_vertices", "feature_admm_iterations")),
    ("--features dihedral (the default) on a single mesh",
     lambda c: c.mode == MESH and c.features != "l1", ("feature_angle_deg",)),
    ("an input that is not an animation", lambda c: c.mode in (MESH, CLOUD), LOAD_METRICS),
)
"""Which metrics each mode and option reports (every name of ``METRICS`` in one
group): a --check on one that the run's options cannot report is refused before
the input is read. precision, recall, f1 and true_outliers also need an
'outlier' property in the input: a check on them is refused once the input is
read without one, before the work."""


def denoise_mode(input: str, outliers: bool, dynamic: bool) -> str:
    """MESH, CLOUD, MOVING_CLOUD or DYNAMIC, from the options and the input's path."""
    if outliers:
        return MOVING_CLOUD if input != "-" and is_animation_path(input) else CLOUD
    return DYNAMIC if dynamic else MESH


class Choices(NamedTuple):
    """What decides which metrics a run reports, known before the input is read."""

    mode: str
    method: str
    features: str
    refined: bool
    reference: str | None


def _metric_needs(choices: Choices) -> dict[str, tuple[str, ...]]:
    """For each way of running not taken, the metrics only it reports (for
    ``command_run``'s ``needs``: a --check on one of them is refused before the
    input is read)."""
    return {what: names for what, reports, names in MODE_METRICS if not reports(choices)}


_FEATURE_OPTIONS = ("features", "feature_tau", "feature_angle")
_OUTLIER_OPTIONS = ("k", "threshold", "keep_all", "refined")
OUTLIER_BYTES = 150
"""Memory of --outliers per point and neighbour (the stacked neighbourhoods and
RPCA's matrices): 1.38 GB at k = 400 on 20,000 points, 0.51 GB at k = 100."""
SCORED_METRICS = ("true_outliers", "precision", "recall", "f1")
"""The --outliers metrics that need an 'outlier' property in the input."""
ANIMATION_OUTLIER_BYTES = 110
"""Memory of --outliers on a moving cloud per coordinate of the input (the
animation matrix and RPCA's copies of it): 1.24 GB for 20 frames of 200,000
points."""


def _unused_option_groups(mode: str, features: str, method: str) -> list[tuple[tuple[str, ...], str]]:
    """The options (parameter names) the mode does not use, in groups with
    the reason a given one is refused."""
    groups = []
    if mode in (CLOUD, MOVING_CLOUD):
        groups.append((_FILTER_OPTIONS + _FEATURE_OPTIONS, "not used by --outliers"))
        groups.append((("reference",), "not used by --outliers (precision, recall and F1 come from the "
                       "input's 'outlier' property)"))
        if mode == MOVING_CLOUD:
            groups.append((("k", "keep_all", "no_clean"), "not used for an animation (its outliers come "
                           "from the animation matrix, every point is written, frames are read as stored)"))
    else:
        groups.append((_OUTLIER_OPTIONS, "only with --outliers"))
    if mode == DYNAMIC:
        groups.append((_FEATURE_OPTIONS + ("no_clean",), "not used by --dynamic (the animation output has no "
                       "feature property; frames are read as stored)"))
    else:
        groups.append((("coherence",), "only with --dynamic"))
    groups.append((("feature_angle",), "only with --features dihedral") if features == "l1"
                  else (("feature_tau",), "only with --features l1"))
    if method != "guided" and mode not in (CLOUD, MOVING_CLOUD):
        groups.append((("guidance_mix",), "only with --method guided"))
    return groups


def _options_not_used(mode: str, features: str, method: str) -> dict:
    """The report's values of the options the mode does not use (None, as
    :func:`_refuse_unused_options` refuses them when given; ``no_clean`` is
    the report's ``clean``)."""
    return {("clean" if name == "no_clean" else name): None
            for names, _ in _unused_option_groups(mode, features, method) for name in names}


def _refuse_unused_options(ctx: typer.Context, mode: str, features: str, method: str) -> None:
    """Options the chosen mode would ignore are refused (exit 2), not dropped."""
    for names, reason in _unused_option_groups(mode, features, method):
        refuse_options(ctx, names, reason)


def _mesh(run, input, output, reference, method, dp, no_clean, given: list[str]) -> None:
    run.one_stdin(input, reference)
    if input != "-" and is_animation_path(input):
        kind = "a folder" if os.path.isdir(input) else "a .npz file"
        raise UsageError(f"{input}: {kind} is read as an animation; --dynamic denoises it, --outliers finds "
                         "its outlying points")
    mesh = run.load_mesh(input, clean=not no_clean, mesh_output=output)
    path = mesh.log.path or None
    if mesh.is_point_cloud:
        raise InputError(path, "is a point cloud (no faces); use --outliers for point clouds")
    if no_clean:
        run.note_kept_seams(mesh, path or input)
    require_triangle_mesh(mesh)  # the edge check is denoise_mesh's own, its error named below
    # the filters (scipy, the compiled kernels) load once the input is read
    from geoproc.denoise.mesh_denoise import denoise_mesh
    from geoproc.denoise.metrics import reference_metrics
    from geoproc.denoise.scale_groups import SCALE_RATIO
    from geoproc.denoise.validate import reference_in_input_order

    ref_V = None
    if reference is not None:
        ref = run.read_input(reference, lambda name, data: load_mesh(name, clean=not no_clean, stdin_bytes=data))
        ref_V = reference_in_input_order(mesh.F, len(mesh.V), ref.F, ref.V, reference,
                                         counts_hint=" (if it is, load both with the same --no-clean setting)")
    with run.timer("denoise"), run.progress(f"denoise ({method})") as update, _naming_the_input(path or input):
        res = denoise_mesh(mesh.V, mesh.F, method, dp, progress=update)
    out = Mesh(res.V, mesh.F, dict(mesh.vertex_fields), dict(mesh.face_fields))
    run.refresh_normals(out.V, out.F, out.vertex_fields)
    run.note_replaced("face", ["feature"], out.face_fields)
    out.face_fields["feature"] = res.feature
    run.metrics.update({"vertices": len(res.V), "faces": len(mesh.F),
                        "feature_faces": int(res.feature.sum())})
    run.metrics.update({k: v for k, v in res.info.items() if v is None or np.isscalar(v)})  # None: did not act
    if res.info.get("scale_groups", 1) > 1:
        ran = res.info.get("outer_iterations") and res.info.get("normal_iterations")
        which = ("the largest group that was filtered" if ran else
                 "the largest group; none was filtered, each reads as clean"
                 if dp.outer_iterations is None and dp.normal_iterations is None else
                 "the largest group; no filter pass ran")
        run.note(f"{path or input}: its parts are meshed at scales more than {SCALE_RATIO:g} times apart; "
                 f"denoised in {res.info['scale_groups']} groups, each with the schedule its own noise gives "
                 f"(the schedule's metrics are those of {which}; given back as options, they would apply to "
                 "every group)")
    _note_unused_filter_options(run, res.info, dp, given)
    if ref_V is not None:
        with run.timer("metrics"):
            run.metrics.update(reference_metrics(res.V, mesh.V, mesh.F, ref_V))
    run.write_mesh(output, out)


@contextmanager
def _naming_the_input(path: str):
    """Errors the method finds in the data (a problem of the mesh, or an
    option too small for its spacing) name the input file."""
    try:
        yield
    except InputError as exc:
        if exc.path is not None:
            raise
        raise InputError(path, exc.problem) from None
    except UsageError as exc:
        raise UsageError(f"{path}: {exc}") from None


def _note_unused_filter_options(run, info: dict, dp, given: list[str]) -> None:
    """A note when options were given (``given``: their flags) for work that
    did not run: the filter's when no filter pass ran (the mesh read as clean,
    or --rounds / --normal-iterations 0), the vertex update's when no round
    ran, --fidelity when no vertex sweep ran; --method guided when its guidance
    was blended away (``guidance_mix`` 1 chosen from the input: the plain
    bilateral filter)."""
    rounds = info.get("outer_iterations", 1)
    filtered = rounds and info.get("normal_iterations", 1)
    # with --normal-iterations 0 the crease repair's narrow passes still run in the last round,
    # with --sigma-s but their own sigma_r and pure guidance (--sigma-s had been called unused)
    narrow = bool(rounds) and not filtered and info.get("sigma_s") is not None
    counts = (("--rounds", "outer_iterations", dp.outer_iterations),
              ("--normal-iterations", "normal_iterations", dp.normal_iterations))
    zero = [opt for opt, _, value in counts if value == 0]  # the cause, not an unused option
    # (--method decides whether the crease repair runs: used whenever a round ran)
    filter_options = ("--sigma-r", "--guidance-mix", "--normal-iterations") + (() if narrow else ("--sigma-s",))
    unused = [o for o in given if o in filter_options and not filtered]
    unused += [o for o in given if o in ("--method", "--vertex-iterations", "--fidelity", "--crease-repair")
               and not rounds]
    unused = [o for o in unused if o not in zero]
    if unused:
        if zero and narrow:
            from geoproc.denoise.mesh_denoise import FINE_FINAL_SIGMA_R

            why = (f"no pass of the schedule ran ({' and '.join(opt + ' 0' for opt in zero)}); the last round's "
                   f"narrow guided passes, which did, use a sigma_r of {FINE_FINAL_SIGMA_R:g} and the guidance alone")
        elif zero:
            why = f"no filter pass ran ({' and '.join(opt + ' 0' for opt in zero)})"
        else:
            why = (f"the mesh reads as clean (roughness {info.get('noise_roughness', float('nan')):.3g}), so "
                   f"nothing was filtered; give {_options_to_filter(dp)} to filter anyway")
        run.note(f"{', '.join(unused)} not used: {why}")
    elif rounds and not filtered and dp.outer_iterations and dp.normal_iterations is None:
        # --rounds given, the passes left to the schedule, which gives none on a clean mesh
        run.note(f"no filter pass ran: the mesh reads as clean (roughness "
                 f"{info.get('noise_roughness', float('nan')):.3g}), so --normal-iterations defaults to 0 in "
                 f"each of the {rounds} rounds; give --normal-iterations to filter")
    elif not rounds and dp.outer_iterations is None:  # nothing given, nothing done: said (it had been silent)
        run.note(f"the mesh reads as clean (roughness {info.get('noise_roughness', float('nan')):.3g}): nothing "
                 f"was filtered and the positions are written unchanged; give {_options_to_filter(dp)} (above 0) to "
                 "filter anyway")
    if (filtered and "--method" in given and "--guidance-mix" not in given and dp.guidance_mix is None
            and info.get("guidance_mix") == 1.0 and not info.get("crease_repair")):
        run.note("--method guided: at this noise level on this mesh the guidance is blended away "
                 "(guidance_mix 1: the plain bilateral filter); --guidance-mix sets it")
    if rounds and "--fidelity" in given and not info.get("vertex_iterations", 1):
        run.note("--fidelity not used: no vertex sweep ran (--vertex-iterations 0)")


def _options_to_filter(dp) -> str:
    """The counts a clean mesh leaves at 0 that would make the filter run: of
    --rounds and --normal-iterations, those not given or given as 0."""
    return " and ".join(opt for opt, value in (("--rounds", dp.outer_iterations),
                                               ("--normal-iterations", dp.normal_iterations)) if not value)


def _refuse_scored_checks(run, name: str) -> None:
    """A --check on the detection scores of an input ``name`` without an 'outlier'
    property is refused before the work (there is nothing to score against)."""
    run.refuse_unmeasurable_checks(SCORED_METRICS, f"{name} has no 'outlier' property to score against "
                                                   "(perturb --outliers writes one)")


def _outliers(run, input, output, k, threshold, keep_all, refined, no_clean) -> None:
    if k < 4:
        raise UsageError(f"--k {k}: must be at least 4")
    cloud = run.load_mesh(input, clean=not no_clean, mesh_output=output)
    n = len(cloud.V)
    if k > n:  # before the memory it would need: that had been the error, beyond the machine's memory
        raise InputError(cloud.log.path or input, f"has {n} point{'s' if n != 1 else ''}, fewer than the "
                                                  f"neighbourhood size k={k}")
    # (a k beyond the distinct points is refused by the method, naming their count)
    require_memory(OUTLIER_BYTES * n * k, f"--k {k} on {n} points")
    if "outlier" not in cloud.vertex_fields:
        _refuse_scored_checks(run, cloud.log.path or input)
    from geoproc.denoise.outliers import detection_scores, rpca_outliers

    path = cloud.log.path or None
    with run.timer("outliers"):
        res = rpca_outliers(cloud.V, k=k, threshold=threshold, path=path)
    run.metrics.update({"points": len(cloud.V), "detected_outliers": int(res.outlier.sum()),
                        "threshold": res.threshold})
    if "outlier" in cloud.vertex_fields:
        truth = run.outlier_flags(cloud.vertex_fields["outlier"], (len(cloud.V),), path or input)
        run.metrics["true_outliers"] = int(truth.sum())
        run.metrics.update(detection_scores(res.outlier, truth))
    P = res.refined if refined else cloud.V
    if refined:
        run.metrics["mean_refinement_shift"] = float(np.linalg.norm(res.refined - cloud.V, axis=1).mean())
    if not keep_all and res.outlier.all():
        raise InputError(path or input, f"every point scores above the threshold {res.threshold:.6g}; no "
                         "inlier to write (raise --threshold, or --keep-all writes every point with its score)")
    if keep_all:  # every point, so the faces stay as they are
        out = Mesh(P, cloud.F, dict(cloud.vertex_fields), dict(cloud.face_fields))
        run.note_replaced("vertex", SCORE_FIELDS, out.vertex_fields)
        out.vertex_fields["outlier_score"] = res.score
        out.vertex_fields["outlier_detected"] = res.outlier.astype(np.float64)
    else:
        out = _inliers(run, _without_earlier_scores(run, cloud), P, ~res.outlier, path or input)
    if refined:  # moved vertices: a mesh's stored normals follow them (a cloud's stay)
        run.refresh_normals(out.V, out.F, out.vertex_fields)
    run.write_mesh(output, out)


def _without_earlier_scores(run, cloud: Mesh) -> Mesh:
    """``cloud`` without the vertex properties an earlier ``--keep-all`` run wrote
    (:data:`SCORE_FIELDS`), with a note: carried into the inliers, they would
    contradict this run (points flagged 1 among the points it kept)."""
    stale = [k for k in SCORE_FIELDS if k in cloud.vertex_fields]
    if not stale:
        return cloud
    run.note("dropping the input's vertex propert" + ("y " if len(stale) == 1 else "ies ")
             + ", ".join(f"'{k}'" for k in stale) + " (an earlier run's scores; --keep-all writes this run's)")
    fields = {k: v for k, v in cloud.vertex_fields.items() if k not in stale}
    return Mesh(cloud.V, cloud.F, fields, cloud.face_fields)


def _inliers(run, cloud: Mesh, P: np.ndarray, keep: np.ndarray, name: str) -> Mesh:
    """The inlier points (positions P, vertex properties) and the input's faces
    whose three corners are inliers, renumbered (with their properties); a note
    on the input ``name`` counts the faces left out."""
    new = np.cumsum(keep) - 1
    whole = keep[cloud.F].all(axis=1)  # (0,) for a point cloud's (0, 3) faces
    if not whole.all():
        run.note(f"{name}: {int((~whole).sum())} of {len(cloud.F)} faces use a removed point and are left out")
    return Mesh(P[keep], new[cloud.F[whole]].reshape(-1, 3),
                {name: v[keep] for name, v in cloud.vertex_fields.items()},
                {name: v[whole] for name, v in cloud.face_fields.items()})


SCORE_FIELDS = ("outlier_score", "outlier_detected")


def _animation_outliers(run, input, output, threshold, refined) -> None:
    require_animation_output(output)
    anim = run.load_animation(input, output)
    require_memory(ANIMATION_OUTLIER_BYTES * anim.V.size,
                   f"--outliers on {anim.n_frames} frames of {anim.V.shape[1]} points")
    if "outlier" not in anim.fields:
        _refuse_scored_checks(run, anim.path)
    from geoproc.denoise.outliers import detection_scores, rpca_animation_outliers

    with run.timer("outliers"):
        res = rpca_animation_outliers(anim.V, threshold, path=anim.path)
    run.metrics.update({"frames": anim.n_frames, "points": int(anim.V.shape[1]),
                        "detected_outliers": int(res.outlier.sum()), "threshold": res.threshold,
                        "motion_basis": res.rank, "rpca_iterations": res.rpca_iterations})
    if "outlier" in anim.fields:
        truth = run.outlier_flags(anim.fields["outlier"], anim.V.shape[:2], anim.path, anim.frame_files)
        run.metrics["true_outliers"] = int(truth.sum())
        run.metrics.update(detection_scores(res.outlier, truth))
    fields = dict(anim.fields)
    run.note_replaced("vertex", SCORE_FIELDS, fields)
    fields["outlier_score"] = res.score
    fields["outlier_detected"] = res.outlier.astype(np.float64)
    V = res.refined if refined else anim.V
    if refined:
        run.refresh_normals(V, anim.F, fields)
    run.write_animation(output, Animation(V, anim.F, fields, output))


def _dynamic(run, input, output, reference, method, dp, coherence) -> None:
    if input == "-":  # (np.load needs a file it can seek in)
        raise UsageError("-: --dynamic reads an animation from a file or folder (.npz or frame meshes), "
                         "not from standard input")
    if not os.path.exists(input):
        raise InputError(input, "no such file or folder")
    if not is_animation_path(input):
        raise UsageError(f"{input}: --dynamic needs an animation (.npz or a folder of frame meshes)")
    require_animation_output(output)
    anim = run.load_animation(input, output)
    if anim.n_frames < 3:
        raise InputError(anim.path, f"has {anim.n_frames} frame{'s' if anim.n_frames != 1 else ''}; --dynamic "
                         "needs at least 3 (save a single frame as a mesh file and denoise it without --dynamic)")
    require_triangle_frames(anim.V, anim.F, anim.path, anim.frame_files)
    from geoproc.denoise.dynamic import denoise_animation
    from geoproc.denoise.metrics import reference_metrics
    from geoproc.denoise.validate import reference_in_input_order, require_denoisable
    from geoproc.mesh.topology import faces_with_distinct_corners

    require_denoisable(faces_with_distinct_corners(anim.F), anim.path)  # those are left out, as for a mesh
    if "outlier" in anim.fields:  # carried to the output: refused as perturb and --outliers refuse it
        outlier_flags(anim.fields["outlier"], anim.V.shape[:2], anim.path, anim.frame_files)
    ref_V = None
    if reference == "-":
        raise UsageError("--reference -: an animation reference is read from a .npz file or a folder")
    if reference is not None and not is_animation_path(reference):
        raise UsageError(f"--reference {reference}: with --dynamic the reference is an animation (.npz or a "
                         "folder of frame meshes)")
    if reference is not None:
        ref = run.load_animation(reference)
        if ref.V.shape != anim.V.shape:
            raise InputError(reference, f"reference has {ref.V.shape[0]} frames of {ref.V.shape[1]} "
                             f"vertices; the input {anim.V.shape[0]} of {anim.V.shape[1]}")
        ref_V = reference_in_input_order(anim.F, anim.V.shape[1], ref.F, ref.V, reference)
    with run.timer("denoise"), run.progress("denoise (dynamic)") as update, _naming_the_input(anim.path):
        V, info = denoise_animation(anim.V, anim.F, method, dp, progress=update, coherence=coherence)
    run.metrics.update({"frames": anim.n_frames, "vertices": int(anim.V.shape[1]), "faces": len(anim.F),
                        "vertex_iterations": dp.vertex_iterations,
                        "fidelity": dp.fidelity if dp.vertex_iterations > 0 else None})  # (it acts in the sweeps)
    run.metrics.update({k: v for k, v in info.items() if v is None or np.isscalar(v)})  # None: did not act
    if not info.get("outer_iterations"):  # no frame's static step ran a round: its fit did not act
        run.metrics.update({"vertex_iterations": None, "fidelity": None})
        if dp.outer_iterations is None:
            run.note(f"every frame reads as clean: the static step filtered none (give {_options_to_filter(dp)} "
                     "(above 0) to filter anyway); the temporal coherence step still ran")
    if ref_V is not None:
        with run.timer("metrics"):
            per = [reference_metrics(V[t], anim.V[t], anim.F, ref_V[t]) for t in range(anim.n_frames)]
            for key in per[0]:  # face counts summed over the frames, the largest angle, the rest averaged
                values = [p[key] for p in per]
                run.metrics[key] = (int(sum(values)) if key.endswith("flipped_faces") else
                                    float(max(values)) if key == "max_normal_angle_deg" else float(np.mean(values)))
    fields = dict(anim.fields)
    run.refresh_normals(V, anim.F, fields)
    run.write_animation(output, Animation(V, anim.F, fields, output))


def register(app: typer.Typer) -> None:
    """Add ``denoise`` to the application."""
    app.command("denoise", epilog=metrics_epilog(METRICS, TEXT_METRICS, units=METRIC_UNITS))(denoise)
