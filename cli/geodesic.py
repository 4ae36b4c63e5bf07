"""``geoproc geodesic``: distance to source vertices by exact or heat-based methods."""

from __future__ import annotations

import os
import re
from enum import Enum, StrEnum
from typing import Annotated

import numpy as np
import typer

from geoproc.errors import InputError, UsageError
from geoproc.fileio import read_input_bytes
from geoproc.geodesic.names import (
    DEFAULT_LAPLACIAN,
    DEFAULT_OPERATORS,
    HEAT_UNDERFLOW,
    LAPLACIANS,
    METHODS,
    OPERATORS,
    RENDER_VIEWS,
    SOLVERS,
)
from geoproc_cli.common import (
    LOAD_METRICS,
    CheckOpt,
    DebugOpt,
    NoCleanOpt,
    QuietOpt,
    ReportOpt,
    command_run,
    metrics_epilog,
    options_given,
    refuse_options,
    require_extension,
    require_ply_output,
)

Method = Enum("Method", {m.replace("-", "_"): m for m in METHODS}, type=str)


REFERENCE_METRICS = ("compared_vertices", "nonfinite_vertices", "reference_nonfinite_vertices", "pearson_r", "rmse",
                     "mae", "mean_relative_error", "max_relative_error")
"""The comparison with the reference distances, reported only with ``--reference``."""

METRIC_UNITS = {
    "rmse, mae, mean_relative_error (= mae), max_relative_error":
        "of |d - reference| over the largest reference distance",
    "max_distance, mean_distance, mean_edge_length": "in the mesh's length unit",
    "t": "in its area unit",
}
"""Units of the metrics whose names do not tell, for ``--help``."""

METRICS = LOAD_METRICS + REFERENCE_METRICS + (
    "method", "vertices", "faces", "sources", "mean_edge_length", "t", "t_over_h2", "steps",
    "reachable_vertices", "unreachable_vertices", "nonfinite_distance_vertices", "max_distance", "mean_distance",
    "negative_distance_vertices", "operators", "zero_heat_vertices", "negative_heat_vertices",
    "underflow_heat_vertices", "heat_step_in_log_domain", "solver_inaccurate_steps", "iterations", "min_log_heat",
    "log_heat_below_double", "nonfinite_log_heat",
)
"""Every metric ``geodesic`` can report (which ones a run reports depends on its method and options)."""
TEXT_METRICS = ("method", "operators")
"""The metrics among them that are text (names), which ``--check`` cannot compare."""
UNSTEPPED = ("exact", "heat")
"""Methods without time steps: --steps is refused, and neither params nor metrics hold steps."""


Laplacian = StrEnum("Laplacian", {name.replace("-", "_"): name for name in LAPLACIANS})
Operators = StrEnum("Operators", {name: name for name in OPERATORS})
Solver = StrEnum("Solver", {name: name for name in SOLVERS})
HeatUnderflow = StrEnum("HeatUnderflow", {name.replace("-", "_"): name for name in HEAT_UNDERFLOW})
View = StrEnum("View", {name.replace("-", "minus_"): name for name in RENDER_VIEWS})


MAX_INDEX_DIGITS = 20
"""Digits of the longest vertex index a sources file may spell (2^64 has 20)."""


def read_sources_file(path: str, data: bytes | None = None) -> list[tuple[int, int]]:
    """Vertex indices from a text file (or its content ``data``): integers
    separated by spaces, commas or newlines; ``#`` starts a comment. Returns
    (index, line number) pairs, so that an index out of range names its line."""
    if data is None:
        data = read_input_bytes(path, "file of source indices")
    # a BOM some editors write goes; bytes that are not UTF-8 show as \xNN in an error
    text = data.decode("utf-8", errors="backslashreplace").removeprefix("\ufeff")
    out = []
    for lineno, line in enumerate(text.splitlines(), 1):
        for tok in re.split(r"[\s,]+", line.split("#", 1)[0].strip()):
            if not tok:
                continue
            if not re.fullmatch(r"[+-]?[0-9]+", tok):  # ASCII digits only (no 1_0, no other scripts)
                shown = "".join(c if " " <= c <= "~" else ascii(c)[1:-1] for c in tok)  # non-ASCII escaped
                raise InputError(path, f"line {lineno}: '{shown}' is not a vertex index")
            digits = tok.lstrip("+-").lstrip("0")  # int() counts leading zeros towards its 4300
            if len(digits) > MAX_INDEX_DIGITS:
                raise InputError(path, f"line {lineno}: a {len(digits)}-digit number is beyond any vertex index")
            out.append((int(tok[0] * (tok[0] in "+-") + (digits or "0")), lineno))
    if not out:
        raise InputError(path, "no vertex indices in the file")
    return out


def geodesic(
    ctx: typer.Context,
    mesh: Annotated[str, typer.Argument(help="Triangle mesh: .obj, .ply, .off, .stl, or - for stdin.",
                                        metavar="MESH")],
    output: Annotated[str, typer.Option("--output", "-o", help="Output PLY with the distance per vertex "
                                        "(input scalar vertex and face properties kept); - for stdout.",
                                        metavar="OUT.ply")],
    source: Annotated[list[int] | None, typer.Option("--source", "-s", help="Source vertex index "
                      "(0-based, in the mesh as loaded); repeatable: distance to the nearest. At least one "
                      "source is needed, here or in --sources-file.",
                      metavar="I", show_default=False)] = None,
    sources_file: Annotated[str | None, typer.Option("--sources-file", help="Text file of source indices "
                            "(integers separated by spaces, commas or newlines; # comments); - reads stdin.",
                            metavar="FILE", show_default=False)] = None,
    method: Annotated[Method, typer.Option("--method", "-m", help="exact (MMP), heat (Crane et al.), "
                      "varadhan (sqrt(-4T log u)), log-splitting, log-ode, log-heat. varadhan, log-ode and "
                      "log-splitting tend to the geodesic distance as the time shrinks on a smooth surface, but "
                      "on a mesh a time below a few h^2 adds discretization error: at the defaults (c 1, 1 step) "
                      "their mean error is tens of percent of the largest distance (bunny: 28 %, log-splitting "
                      "91 %; heat 1.1 %), and log-ode on bunny reads 38 % at c 0.1 with 100 steps, 6 % at c 5 "
                      "with 100; see the README's Table 2 protocol.")
                      ] = Method.heat,
    time_factor: Annotated[float, typer.Option("--time-factor", "-c", help="t = c * h^2 with h the mean "
                           "edge length; c > 0 and at most 1e12.")] = 1.0,
    time: Annotated[float | None, typer.Option("--time", "-t", help="Absolute diffusion time (area "
                    "unit), > 0 and at most 1e12 h^2; instead of --time-factor (not both).",
                    show_default=False)] = None,
    steps: Annotated[int, typer.Option("--steps", "-n", help="Backward-Euler steps to reach t "
                     "(varadhan, log-ode, log-splitting, log-heat), 1 to 100000.", min=1, max=100000)] = 1,
    laplacian: Annotated[Laplacian | None, typer.Option("--laplacian", help="Default: intrinsic-delaunay for "
                         "heat, log-ode and log-heat (for heat, its heat step); cotan for varadhan and log-splitting.",
                         show_default=False)] = None,
    operators: Annotated[Operators | None, typer.Option("--operators", help="heat and log-heat: gradient, "
                         "divergence and Poisson Laplacian on the mesh (extrinsic), on its intrinsic Delaunay "
                         "triangulation (intrinsic: no sliver triangles; the heat step then uses its Laplacian "
                         "too), or auto: intrinsic when at least 0.5% of the faces have an angle below 5 "
                         "degrees, any face an angle below 1e-6 rad, or at least 5% of the cotan Laplacian's "
                         "off-diagonal weight is negative (obtuse non-Delaunay triangles). Default: auto.",
                         show_default=False)] = None,
    solver: Annotated[Solver, typer.Option("--solver", help="log-ode solver: lu (log-space LU, fast), "
                      "newton, or cvxpy (Clarabel; reference, slow).")] = Solver.lu,
    heat_underflow: Annotated[HeatUnderflow, typer.Option("--heat-underflow", help="-m heat: where the heat "
                              "step's u falls below the smallest normal double (2.2e-308) at a vertex connected "
                              "to a source (a fine mesh, a short time), log-domain solves that step again in the "
                              "log domain (log-heat's solver, one step; the same distances to rounding where u is "
                              "representable; a time so short that t times a Laplacian weight underflows is "
                              "then refused) and keep keeps the plain step's result (no direction where u is 0).")]
    = HeatUnderflow.log_domain,
    reference: Annotated[str | None, typer.Option(
        "--reference", help="Compare with a reference distance: exact (libigl's exact geodesics from the "
        "same sources), or a file of distances, one per vertex (- for stdin): a .npy, or a mesh with the same "
        "vertices (within 1e-6 of its bounding-box diagonal, float32 copies too) holding them in the vertex "
        "property --reference-field names (another run's output, say); +inf marks vertices no source reaches. "
        "Reports pearson_r, rmse, mae, "
        "mean/max_relative_error.", metavar="exact|FILE", show_default=False)] = None,
    field_name: Annotated[str, typer.Option("--field-name", help="Name of the output vertex property: an identifier "
                                          "(letters, digits, _) other than x, y, z (the positions), nx, ny, nz "
                                          "(the normals), outlier (outlier flags) and end_header.")]
    = "distance",
    reference_field: Annotated[str | None, typer.Option(
        "--reference-field", help="With --reference MESH: the vertex property holding the reference "
        "distances. Default: the --field-name value.", metavar="NAME", show_default=False)] = None,
    render: Annotated[str | None, typer.Option("--render", help="Also draw the mesh colored by distance "
                      "with isolines into this PNG (- for stdout).", metavar="PNG", show_default=False)] = None,
    render_view: Annotated[View, typer.Option("--render-view", help="With --render: the side the mesh is "
                           "seen from, orthographic: z (from +z, x right, y up), -z, x (y right, z up), -x, y "
                           "(-x right, z up) or -y.")] = View.z,
    no_clean: NoCleanOpt = False,
    report: ReportOpt = None,
    check: CheckOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Geodesic distance from source vertices, written as a per-vertex PLY property.

    Vertices not connected to any source get +inf (counted as
    unreachable_vertices). Timings: setup (operators, factorizations) and
    solve (the part repeated for each new source set).
    """
    m_name = method.value
    read_field = field_name if reference_field is None else reference_field  # a reference mesh's property
    params = {
        "mesh": mesh, "output": output, "sources": list(source or []), "sources_file": sources_file,
        "sources_from_file": None,
        # the options that apply: --time replaces -c, and heat and exact take no --steps
        "method": m_name, "time_factor": None if time is not None or m_name == "exact" else time_factor,
        "time": time, "steps": None if m_name in UNSTEPPED else steps,
        "laplacian": laplacian.value if laplacian else DEFAULT_LAPLACIAN.get(m_name),
        "operators": operators.value if operators else DEFAULT_OPERATORS.get(m_name),
        "solver": solver.value if m_name == "log-ode" else None,  # the only method that solves with it
        "heat_underflow": heat_underflow.value if m_name == "heat" else None,
        "reference": reference,
        # the property read from a reference mesh (None for exact or a .npy; set once a '-' is read)
        "reference_field": read_field if reference not in (None, "exact")
        and not str(reference).lower().endswith(".npy") else None,
        "field_name": field_name, "render": render, "render_view": render_view.value if render else None,
        "clean": not no_clean,
    }
    with command_run("geodesic", params, report=report, checks=check, quiet=quiet, debug=debug,
                     outputs=[output, render], inputs=[mesh, sources_file, None if reference == "exact" else reference],
                     metrics=METRICS, text_metrics=TEXT_METRICS,
                     needs=_metric_needs(m_name, solver.value, reference)) as run:
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", field_name) or field_name in ("x", "y", "z"):
            raise UsageError(f"--field-name '{field_name}' must be an identifier other than x, y, z")
        if field_name in ("nx", "ny", "nz", "outlier"):  # had been written, then lost or misread downstream
            what = "vertex normals, which the commands that move vertices recompute" if field_name != "outlier" \
                else "outlier flags, which denoise --outliers scores against"
            raise UsageError(f"--field-name '{field_name}': a PLY property of that name holds {what}; "
                             "choose another name")
        if field_name == "end_header":
            raise UsageError("--field-name 'end_header': PLY readers such as trimesh's take a property of that "
                             "name for the header's end; choose another name")
        require_ply_output(output, "the distance is a vertex property")
        if render is not None:
            require_extension(render, ".png", "--render", stdout_ok=True)
        else:
            refuse_options(ctx, ("render_view",), "only with --render")
        _refuse_unused_options(ctx, m_name, operators.value if operators else None,
                               laplacian.value if laplacian else None)
        if not source and sources_file is None:
            raise UsageError("give at least one source vertex (--source I or --sources-file FILE)")
        if reference_field is not None and not reference_field:
            raise UsageError("--reference-field '': give the name of a vertex property")
        if reference in (None, "exact") or reference.lower().endswith(".npy"):
            refuse_options(ctx, ("reference_field",), "only with --reference MESH (a mesh file holding the "
                                                      "distances as a vertex property)")
        if reference not in (None, "exact", "-") and not os.path.exists(reference):  # before the work
            raise UsageError(f"--reference {reference}: no such file (give exact, or a .npy or mesh file of "
                             "distances)")
        run.one_stdin(mesh, sources_file, None if reference == "exact" else reference)
        m = run.load_mesh(mesh, clean=not no_clean)
        srcs = list(source or [])
        # indices past the loaded mesh, where loading merged or dropped vertices: the stored count differs
        renumbered = bool(m.log.merged_vertices or m.log.removed_unreferenced)
        cleaned = (f"; the mesh file stores {m.log.stored_vertices}, and loading merged {m.log.merged_vertices} "
                   f"coincident and dropped {m.log.removed_unreferenced} unreferenced vertices (--no-clean keeps "
                   "the stored numbering)" if renumbered else "")
        wrong = [i for i in srcs if isinstance(i, int) and not 0 <= i < len(m.V)]
        if wrong:
            raise InputError(m.log.path or mesh, f"source vertex {wrong[0]} is out of range (the mesh has "
                                                 f"{len(m.V)} vertices, numbered from 0{cleaned})")
        if sources_file is not None:  # after the mesh: a second '-' is then the one refused
            listed = run.read_input(sources_file, read_sources_file, "file of source indices")
            for i, lineno in listed:
                if not 0 <= i < len(m.V):
                    raise InputError(sources_file, f"line {lineno}: source vertex {i} is out of range "
                                                   f"(the mesh {m.log.path or mesh} has {len(m.V)} vertices{cleaned})")
            srcs += [i for i, _ in listed]
            run.params["sources_from_file"] = [i for i, _ in listed]  # the report names them: a pipe is gone
        where = m.log.path or mesh  # notes on the mesh name it, as errors do
        if renumbered:
            run.note(f"{where}: source indices refer to the cleaned mesh (--no-clean keeps the stored numbering)")
        stored = None  # --reference FILE, read and checked before the work
        if reference not in (None, "exact"):
            with run.timer("reference"):
                stored = _reference_file(run, reference, m, read_field, no_clean, reference_field is not None)
        # the solvers (scipy, libigl, the compiled kernels) load once the inputs are read
        from geoproc.geodesic.compare import compare_to_reference
        from geoproc.geodesic.distance import geodesic_distance

        with run.progress(f"geodesic {m_name}", 1.0) as update:
            res = geodesic_distance(m.V, m.F, srcs, m_name, time_factor=time_factor, time=time,
                                    steps=steps, laplacian=laplacian.value if laplacian else None,
                                    solver=solver.value, operators=operators.value if operators else None,
                                    path=m.log.path, progress=update, also_exact=reference == "exact",
                                    heat_underflow=heat_underflow.value, load_log=m.log)
        run.timings["setup"] = res.timings.get("setup", 0.0)
        run.timings["solve"] = res.timings.get("solve", 0.0)
        d = res.distance
        fin = np.isfinite(d)
        run.metrics.update({
            "method": m_name, "vertices": m.n_vertices, "faces": m.n_faces,
            "sources": len(set(srcs)), "mean_edge_length": res.h,
            "reachable_vertices": int(m.n_vertices - res.stats["unreachable_vertices"]),
            "nonfinite_distance_vertices": int((~fin).sum() - res.stats["unreachable_vertices"]),
            "max_distance": float(d[fin].max()) if fin.any() else None,
            "mean_distance": float(d[fin].mean()) if fin.any() else None,
        })
        if res.t is not None:  # exact has no diffusion time, heat and exact no time steps: not reported
            run.metrics.update({"t": res.t, "t_over_h2": res.t / res.h**2})
        if m_name not in UNSTEPPED:
            run.metrics["steps"] = steps
        run.metrics.update(res.stats)
        if res.stats.get("operators") == "intrinsic":  # the heat step used the intrinsic Laplacian too
            run.params["laplacian"] = "intrinsic-delaunay"
        if laplacian is not None and laplacian.value != "intrinsic-delaunay" and \
                res.stats.get("operators") == "intrinsic":  # auto chose intrinsic
            run.note(f"--laplacian {laplacian.value} not used: --operators auto chose the intrinsic operators "
                     "on this mesh (slivers or strongly non-Delaunay triangles); give --operators extrinsic "
                     "to use it")
        if m_name == "heat" and res.stats.get("underflow_heat_vertices"):
            what = (f"{res.stats['underflow_heat_vertices']} vertices where heat u underflowed below the smallest "
                    f"normal double ({res.stats['zero_heat_vertices']} to 0)")
            if res.stats["heat_step_in_log_domain"]:
                what += ": the heat step was solved again in the log domain (--heat-underflow keep: the plain step)"
            elif heat_underflow.value == "log-domain":
                what += "; the log domain needs non-negative weights: their directions may be lost"
            else:
                what += "; their directions may be lost (--heat-underflow log-domain keeps them)"
            run.note(f"{where}: {what}")
        if m_name == "heat" and res.stats.get("negative_heat_vertices"):  # (it had gone without a word)
            cotan = run.params.get("laplacian") == "cotan"
            run.note(f"{where}: {res.stats['negative_heat_vertices']} vertices got negative heat"
                     + (" (the cotan weights of obtuse triangles are negative)" if cotan else "")
                     + ": the normalized gradient points the wrong way there"
                     + ("; the default --laplacian intrinsic-delaunay has no negative weight" if cotan else ""))
        for key in ("zero_heat_vertices", "log_heat_below_double"):
            if res.stats.get(key) and m_name != "heat":
                what = "heat u underflowed to 0" if key == "zero_heat_vertices" else "exp(log u) < 5e-324"
                run.note(f"{where}: {res.stats[key]} vertices where {what}")
        if res.stats.get("solver_inaccurate_steps"):
            run.note(f"Clarabel ended {res.stats['solver_inaccurate_steps']} of the {steps} steps short of its "
                     "tolerances (status optimal_inaccurate); --solver lu solves the same steps")
        if res.stats["unreachable_vertices"]:
            run.note(f"{where}: {res.stats['unreachable_vertices']} vertices are not connected to a source "
                     "(distance +inf)")
        if run.metrics["nonfinite_distance_vertices"]:
            why = (" (the heat there is 0 or negative, and Varadhan's formula takes its log; a larger "
                   "--time-factor or -m log-heat gives them one)" if m_name == "varadhan" else "")
            run.note(f"{where}: {run.metrics['nonfinite_distance_vertices']} vertices connected to a source have no "
                     f"finite distance{why}: nonfinite_distance_vertices counts them")
        if reference == "exact":
            with run.timer("reference"):  # -m exact is its own reference: not computed twice
                stored = d if m_name == "exact" else geodesic_distance(m.V, m.F, srcs, "exact",
                                                                       path=m.log.path).distance
        if stored is not None:
            run.metrics.update(compare_to_reference(d, stored))
            if run.metrics["reference_nonfinite_vertices"]:
                run.note(f"{run.metrics['reference_nonfinite_vertices']} vertices with a finite distance have none "
                         "in the reference (it does not reach them: other sources or another mesh?); they are "
                         "not compared, reference_nonfinite_vertices counts them")
        out = m.copy()
        run.note_replaced("vertex", [field_name], out.vertex_fields)
        out.vertex_fields[field_name] = d
        run.write_mesh(output, out)
        if render is not None:
            from geoproc.geodesic.render import render_distance_png, seen_area_pixels

            if seen_area_pixels(m.V, m.F, render_view.value) < 900:  # (the picture had been blank, no word)
                run.note(f"--render {render}: every face is seen edge-on from --render-view {render_view.value}: "
                         "the picture shows next to nothing of the surface; another view shows it")
            with run.timer("render"):
                title = f"{os.path.basename(mesh)}: {m_name}"
                run.write_bytes(render, render_distance_png(m.V, m.F, d, sorted(set(srcs)), view=render_view.value,
                                                            title=title))



METHOD_METRICS = (
    # (what reports them, the methods that do, with the log-ode solver where it matters, the metrics)
    ("a diffusion method (not -m exact)", tuple(m for m in METHODS if m != "exact"), ("t", "t_over_h2")),
    ("-m varadhan, log-splitting, log-ode or log-heat (time steps)",
     tuple(m for m in METHODS if m not in UNSTEPPED), ("steps",)),
    ("-m heat or log-heat", ("heat", "log-heat"), ("negative_distance_vertices", "operators")),
    ("-m heat or varadhan", ("heat", "varadhan"), ("zero_heat_vertices", "negative_heat_vertices")),
    ("-m heat", ("heat",), ("underflow_heat_vertices", "heat_step_in_log_domain")),
    ("-m log-splitting, log-ode or log-heat", ("log-splitting", "log-ode", "log-heat"),
     ("min_log_heat", "log_heat_below_double", "nonfinite_log_heat")),
    ("-m log-ode --solver lu or newton", ("log-ode lu", "log-ode newton"), ("iterations",)),
    ("-m log-ode --solver cvxpy", ("log-ode cvxpy",), ("solver_inaccurate_steps",)),
)
"""The metrics only some methods report: a --check on one that the chosen method
does not report is refused before the input is read."""


def _reference_file(run, path: str, m, field_name: str, no_clean: bool, named: bool = False) -> np.ndarray:
    """The reference distances of ``--reference FILE`` for the vertices of
    ``m``: a .npy with one value per vertex (by its extension, or on standard
    input by its first bytes), or the ``field_name`` property of a mesh with
    the same vertices (loaded as the input was; ``named``: given by
    --reference-field, which a .npy on standard input refuses). Finite values
    and +inf (unreached) only, some of them above 0."""
    from geoproc.mesh import load_mesh
    from geoproc.mesh.validate import npy_vertex_values, scalar_vertex_properties

    def read(name: str, data: bytes | None):
        if name.lower().endswith(".npy") or (data is not None and data.startswith(b"\x93NUMPY")):
            if named:
                raise UsageError("--reference-field: the reference on standard input is a .npy, which has no "
                                 "vertex properties")
            run.params["reference_field"] = None
            return npy_vertex_values(data, m, name).reshape(-1)
        ref = load_mesh(name, clean=not no_clean, stdin_bytes=data)
        if len(ref.V) != len(m.V):
            raise InputError(name, f"the reference mesh has {len(ref.V)} vertices, the mesh {len(m.V)}: it must "
                                   "be the same mesh, holding the distances as a vertex property")
        far = np.linalg.norm(ref.V - m.V, axis=1)
        diag = float(np.linalg.norm(np.ptp(m.V, axis=0))) if len(m.V) else 0.0
        # a float32 copy (as many tools write) rounds each coordinate by up to 2^-24 of its size
        allowed = 1e-6 * diag + 2.0**-22 * float(np.abs(m.V).max(initial=0.0))
        if far.max(initial=0.0) > allowed:
            i = int(np.argmax(far))
            raise InputError(name, f"the reference mesh's vertex {i} is {far[i]:.3g} from the mesh's (more than "
                                   "1e-6 of its bounding-box diagonal and float32 rounding): it must be the same "
                                   "mesh, with its vertices in the same order")
        values = ref.vertex_fields.get(field_name)
        if values is None or values.ndim != 1:
            option = "--reference-field" if named else "--field-name; --reference-field names another"
            raise InputError(name, f"no vertex property '{field_name}' ({option}) holds the reference "
                                   f"distances (scalar properties: {scalar_vertex_properties(ref)})")
        return values

    npy = path.lower().endswith(".npy")
    values = run.read_input(path, read, "reference distances (.npy)" if npy else None)
    if values.dtype.kind not in "fiu":
        raise InputError(path, f"reference distances must be real numbers, got dtype {values.dtype}")
    values = np.asarray(values, dtype=np.float64)
    if len(values) != len(m.V):
        raise InputError(path, f"{len(values)} reference distances for {len(m.V)} vertices")
    bad = np.isnan(values) | (values == -np.inf)
    if bad.any():
        are = "distances are" if bad.sum() > 1 else "distance is"
        raise InputError(path, f"{int(bad.sum())} reference {are} NaN or -inf (first: vertex "
                               f"{int(np.flatnonzero(bad)[0])}); +inf marks vertices no source reaches")
    if not (np.isfinite(values) & (values > 0)).any():
        raise InputError(path, "no reference distance is finite and above 0: the errors are measured against "
                               "the largest")
    return values


def _metric_needs(method: str, solver: str, reference) -> dict[str, tuple[str, ...]]:
    """The metrics this run will not report, by what would report them (for
    ``command_run``'s ``needs``: a --check on them is refused before the work)."""
    needs: dict[str, tuple[str, ...]] = {}
    if reference is None:
        needs["--reference"] = REFERENCE_METRICS
    for what, methods, names in METHOD_METRICS:
        if method not in methods and f"{method} {solver}" not in methods:
            needs[what] = names
    return needs


def _refuse_unused_options(ctx: typer.Context, method: str, operators: str | None,
                           laplacian: str | None = None) -> None:
    """Options the method would ignore are refused (exit 2), not dropped.
    ``--laplacian intrinsic-delaunay`` with ``--operators intrinsic`` says what
    runs, as a report records it, and passes (a report's params given back as
    options had been refused)."""
    if method == "exact":
        refuse_options(ctx, ("time_factor", "time", "laplacian"), "not used by -m exact (no diffusion)")
    if len(options_given(ctx, "time_factor", "time")) == 2:
        raise UsageError("--time-factor and --time: give one (--time is the absolute t, --time-factor t / h^2)")
    if method in UNSTEPPED:
        refuse_options(ctx, ("steps",), f"not used by -m {method} (no time stepping)")
    if method != "log-ode":
        refuse_options(ctx, ("solver",), "only with -m log-ode")
    if method != "heat":
        refuse_options(ctx, ("heat_underflow",), "only with -m heat")
    if method not in ("heat", "log-heat"):
        refuse_options(ctx, ("operators",), "only with -m heat or -m log-heat")
    if operators == "intrinsic" and laplacian != "intrinsic-delaunay":
        refuse_options(ctx, ("laplacian",), "not used with --operators intrinsic (its Laplacian is the "
                       "intrinsic Delaunay one throughout)")


def register(app: typer.Typer) -> None:
    """Add ``geodesic`` to the application."""
    app.command("geodesic", epilog=metrics_epilog(METRICS, TEXT_METRICS, units=METRIC_UNITS))(geodesic)
