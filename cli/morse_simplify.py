"""``geoproc morse-simplify``: critical points, persistence and optimal
topological simplification of a vertex function on a surface mesh."""

from __future__ import annotations

import os
from typing import Annotated

import numpy as np
import typer

from geoproc.errors import UsageError
from geoproc.fileio import read_input_bytes
from geoproc.mesh import Mesh
from geoproc.mesh.validate import require_edge_manifold, require_triangle_mesh, require_vertex_manifold
from geoproc.report import json_bytes
from geoproc_cli.common import (
    LOAD_METRICS,
    CheckOpt,
    DebugOpt,
    NoCleanOpt,
    QuietOpt,
    ReportOpt,
    command_run,
    flag,
    metrics_epilog,
    refuse_options,
    require_extension,
    require_ply_output,
)

BARYCENTRIC_METRICS = ("subdivision_vertices",)
"""Reported only with ``--barycentric``."""

METRICS = LOAD_METRICS + BARYCENTRIC_METRICS + (
    "vertices", "faces", "minima_before", "saddles_before", "maxima_before", "minima_after", "saddles_after",
    "maxima_after", "euler_characteristic", "betti_0", "betti_1", "betti_2", "pairs_removed", "pairs_kept",
    "max_abs_change", "threshold", "vertices_beyond_half_threshold",
)
"""Every metric ``morse-simplify`` can report (``subdivision_vertices`` with --barycentric)."""
METRIC_UNITS = {
    "threshold": "P in the field's units (with --relative, P times the field's range)",
    "max_abs_change": "max |f - g| in the field's units",
}
"""Units of the metrics whose names do not tell, for ``--help``."""


def morse_simplify(
    ctx: typer.Context,
    mesh: Annotated[str, typer.Argument(help="Triangle mesh (.ply, .obj, .off, .stl), or - for stdin; "
                                        "must be a 2-manifold (boundary and several components are fine; "
                                        "see --split-nonmanifold for vertices where fans of faces meet).",
                                        metavar="MESH")],
    field: Annotated[str, typer.Option(
        "--field", "-f",
        help="The vertex function: a per-vertex PLY property (e.g. 'distance' from geoproc geodesic), "
        "x, y or z, a .npy file with one value per vertex, mean-curvature (1/length) or gaussian-curvature "
        "(1/length^2; both libigl; a vertex property of that name is read instead; the curvature an "
        "earlier run wrote is read as -f mean_curvature).",
        metavar="SPEC", show_default=False)],
    persistence: Annotated[float, typer.Option(
        "--persistence", "-p",
        help="Remove every critical pair with persistence below this threshold P (>= 0, in the field's units; "
        "with --relative a fraction of its range), keep the others.",
        metavar="P", show_default=False)],
    output: Annotated[str, typer.Option(
        "--output", "-o",
        help="Output .ply (or - for binary PLY on stdout): the simplified field as NAME, the input field as "
        "NAME_original, where NAME is x_value, y_value or z_value for a coordinate, mean_curvature or "
        "gaussian_curvature, a vertex property's own name, or a .npy file's stem.", metavar="OUT.ply",
        show_default=False)],
    relative: Annotated[bool, flag(
        "--relative", help="Read P as a fraction of the field's range (max - min).")] = False,
    critical: Annotated[str | None, typer.Option(
        "--critical", help="Write the critical cells before and after, with their pairs, as JSON (- for stdout).",
        metavar="CRIT.json", show_default=False)] = None,
    diagram: Annotated[str | None, typer.Option(
        "--diagram", help="Write the persistence diagrams before and after as a PNG (- for stdout).",
        metavar="PD.png", show_default=False)] = None,
    exact_windows: Annotated[int, typer.Option(
        "--exact-windows",
        help="After the construction, re-solve exactly (a small mixed-integer program each, scipy/HiGHS) "
        "this many windows around the vertices farthest beyond P/2; -1: every such window, then the 8 "
        "farthest again with wider windows (seconds on 10k vertices, tens of seconds on 40k); 0: off; "
        "at least -1.")] = 4,
    barycentric: Annotated[bool, flag(
        "--barycentric",
        help="Write g on the barycentric subdivision of the mesh (every edge and triangle gets a vertex "
        "with its own value; 6 triangles per input triangle), where |f - g| <= P/2 holds (but where the field's "
        "range holds fewer doubles than the subdivision has vertices: breaking ties then moves values farther, "
        "counted in vertices_beyond_half_threshold): f there "
        "is the lower-star extension (each cell's largest vertex value), and the per-vertex property "
        "cell_dim (0, 1, 2) tells input vertices, edge midpoints and triangle centres apart. "
        "--exact-windows is refused with it.")] = False,
    split_nonmanifold: Annotated[bool, flag(
        "--split-nonmanifold",
        help="Give each fan of faces at a non-manifold vertex (where separate fans meet at one point, as "
        "in many scans) its own vertex at the same position, instead of refusing the mesh. The output "
        "then has more vertices than the input; its int property input_vertex gives each one's input "
        "vertex (-1 for the new vertices of --barycentric; reading the output again merges the copies, as "
        "coincident vertices, unless --no-clean is given). Edges with more than two faces are still "
        "refused.")] = False,
    no_clean: NoCleanOpt = False,
    report: ReportOpt = None,
    check: CheckOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Remove topological noise from a function on a surface.

    The discrete gradient of the field is built by ProcessLowerStars (Robins,
    Wood, Sheppard 2011) under the total order (value, then vertex index); its
    critical cells are the minima, saddles (a k-fold saddle counts k times) and
    maxima. Their lower-star persistence pairs decide what is noise: every pair
    with persistence < P is cancelled (Bauer, Lange, Wardetzky 2012), every
    pair with persistence >= P and every essential class stays. With P > 0 the
    output field g has no ties (with P = 0 it is f itself, ties included,
    which the order above breaks by vertex index), its minima and maxima are
    exactly the kept ones, and
    |f - g| <= P/2 except where cancelled basins and peaks interact (a
    vertex function with exactly the kept extrema cannot always stay within
    P/2); those vertices are counted in vertices_beyond_half_threshold
    (moves past P/2 within 64 units in the last place of max |f| are rounding
    and not counted, nor are rises of up to 1e-6 of P/2 that breaking ties
    gave).

    Metrics: minima/saddles/maxima before and after, euler_characteristic,
    betti_0/1/2, pairs_removed, pairs_kept, max_abs_change, threshold,
    vertices_beyond_half_threshold. Timings: field, simplify (gradient, pairs
    and simplification), after (pairs of g), diagram.

    With --barycentric the cancellation is carried out on the cells
    themselves (Forman's path reversal on the lower-star gradient, values
    assigned cell by cell) and g is written on the barycentric subdivision:
    |f - g| <= P/2 everywhere (to the doubles' rounding, as above), the
    critical points of g are the barycentres of the kept critical cells, and
    the "after" counts are taken there.
    """
    persistence = persistence + 0.0  # -0 is 0 (the report had carried -0.0)
    params = {"mesh": mesh, "field": field, "persistence": persistence, "relative": relative,
              "output": output, "critical": str(critical) if critical else None,
              "diagram": str(diagram) if diagram else None,
              "exact_windows": None if barycentric else exact_windows,  # --barycentric holds P/2 without them
              "barycentric": barycentric, "split_nonmanifold": split_nonmanifold, "clean": not no_clean}
    npy_path = field if field.lower().endswith(".npy") else None  # a field read from a file
    with command_run("morse-simplify", params, report=report, checks=check, quiet=quiet, debug=debug,
                     outputs=[output, critical, diagram],
                     inputs=[mesh, npy_path], metrics=METRICS,
                     needs=None if barycentric else {"--barycentric": BARYCENTRIC_METRICS}) as run:
        if not np.isfinite(persistence) or persistence < 0:
            raise UsageError(f"--persistence must be a finite number >= 0, got {persistence:g}")
        if barycentric:
            refuse_options(ctx, ("exact_windows",), "not used with --barycentric (which holds P/2 by construction)")
        if exact_windows < -1:
            raise UsageError(f"--exact-windows must be -1, 0 or a positive count, got {exact_windows}")
        require_ply_output(output, "the fields are vertex properties")
        if diagram is not None:
            require_extension(diagram, ".png", "--diagram", stdout_ok=True)
        if critical is not None:
            require_extension(critical, ".json", "--critical", stdout_ok=True)
        m = run.load_mesh(mesh, clean=not no_clean)
        require_triangle_mesh(m)
        require_edge_manifold(m.F, m.log.path or None, "; morse-simplify needs a manifold mesh", m.log)
        if not split_nonmanifold:
            require_vertex_manifold(m, "; morse-simplify needs a manifold mesh (--split-nonmanifold gives each "
                                       "fan of faces at a vertex its own vertex)")
        # the methods (scipy, the compiled kernels) load once the mesh is read and checked
        from geoproc.mesh.clean import remove_unreferenced_vertices
        from geoproc.mesh.topology import orientation_status, referenced_vertices
        from geoproc.morse import morse_simplify as morse_simplify_field
        from geoproc.morse.barycentric import barycentric_simplify, mesh_cell, subdivision_values
        from geoproc.morse.critical_table import critical_cells_table
        from geoproc.morse.diagram_plot import persistence_diagram_png
        from geoproc.morse.fields import CURVATURES, computes_curvature, field_name, vertex_field
        from geoproc.morse.summary import simplification_summary
        from geoproc.morse.window_repair import TIE_ROUNDING

        npy = read_input_bytes(npy_path, "field file (.npy)") if npy_path else None
        n_vertices = m.n_vertices  # the input's as loaded, for the report
        split, source = _split_fans(run, m, mesh) if split_nonmanifold else (m, None)
        computed = computes_curvature(m, field)
        if field in CURVATURES and not computed:
            run.note(f"--field {field}: read from the input's vertex property of that name (libigl's curvature "
                     "is not computed)")
        with run.timer("field"):  # curvatures of the split surface; the other fields are the input's values
            f = vertex_field(split, field) if computed else vertex_field(m, field, npy)
            if source is not None and not computed:
                f = f[source]
        name = field_name(field, stored=field in m.vertex_fields)
        m = split
        if npy is not None:
            run.add_input(field, npy)
        written = (name, f"{name}_original") + (("cell_dim",) if barycentric else ())
        if split_nonmanifold and name == "input_vertex":
            raise UsageError("--field input_vertex with --split-nonmanifold: the output's 'input_vertex' property "
                             "maps each vertex to its input vertex; copy the field under another name")
        if barycentric and name == "cell_dim":
            raise UsageError("--field cell_dim with --barycentric: the output's 'cell_dim' property holds "
                             "each subdivision vertex's cell dimension; copy the field under another name")
        run.note_replaced("vertex", [k for k in written if k != field], m.vertex_fields)
        used = referenced_vertices(m.F, m.n_vertices)  # (all but under --no-clean)
        if barycentric and not used.all():  # the subdivision is of the surface: they are left out
            run.note(f"{m.log.path or mesh}: {int((~used).sum())} vertices no face uses are left out of the "
                     "subdivision (the output's vertex ids are the subdivision's)")
            V, F, keep = remove_unreferenced_vertices(m.V, m.F)
            m = Mesh(V, F, {k: v[keep] for k, v in m.vertex_fields.items()}, m.face_fields, m.log)
            f, used = f[keep], used[keep]
        span = float(f[used].max() - f[used].min()) if used.any() else 0.0  # the field's range on the surface
        threshold = float(persistence) * span if relative else float(persistence)
        if relative and persistence > 1 and span > 0:  # every pair's persistence is at most the range
            run.note(f"--persistence {persistence:g} --relative is more than the field's whole range: every "
                     "critical pair is removed, and only the critical points the surface's topology needs are left")
        if relative and span == 0.0 and persistence > 0:
            run.note(f"{m.log.path or mesh}: the field is constant on the surface, so --relative makes P 0 "
                     "and nothing is simplified (give P in the field's unit without --relative)")
        if field == "mean-curvature" and computed and not orientation_status(m.F)[0]:
            run.note(f"{m.log.path or mesh}: the surface is not orientable, so the mean curvature's sign "
                     "flips across a seam of it (its magnitude does not)")
        if not np.isfinite(threshold):
            raise UsageError(f"--persistence {persistence:g} --relative: P times the field's range "
                             f"{span:.3g} overflows; use a smaller P")
        with run.timer("simplify"):  # gradient, pairs and simplification
            if barycentric:
                res = barycentric_simplify(m.V, m.F, f, threshold, m.log.path or None)
            else:
                res = morse_simplify_field(m.F, f, threshold, m.log.path or None, exact_windows=exact_windows)
        with run.timer("after"):  # pairs of g, and the checks that tie them to f's
            summary = simplification_summary(res, f, threshold)
        before, after, g = summary.before, summary.after, summary.g
        run.metrics.update({"vertices": n_vertices, "faces": m.n_faces, **summary.metrics})
        beyond, max_change = summary.metrics["vertices_beyond_half_threshold"], summary.metrics["max_abs_change"]
        if beyond:
            run.note(_beyond_note(beyond, threshold, max_change, summary, TIE_ROUNDING))
        if barycentric:
            carried = {k: subdivision_values(res, m.F, v) for k, v in m.vertex_fields.items()}  # interpolated
            if "input_vertex" in carried and name != "input_vertex":  # an index, not a quantity: only
                carried["input_vertex"] = np.where(  # the mesh's own vertices have one (-1 elsewhere)
                    res.dim == 0, carried["input_vertex"], -1).astype(m.vertex_fields["input_vertex"].dtype)
            if name not in ("nx", "ny", "nz"):  # (a normal component simplified as the field stays the field)
                run.refresh_normals(res.V, res.F, carried)  # interpolated normals are neither unit nor the surface's
            elif set(carried) & {"nx", "ny", "nz"} - {name}:  # (had gone without a word)
                others = ", ".join(k for k in ("nx", "ny", "nz") if k in carried and k != name)
                run.note(f"--field {name} with --barycentric: the other normal components ({others}) are "
                         "interpolated on the subdivision, not recomputed, so with the field they are no unit "
                         "vectors there")
            out = Mesh(res.V, res.F, {**carried, name: g, f"{name}_original": summary.f_ref,
                                      "cell_dim": res.dim.astype(np.float64)},
                       {k: np.repeat(v, 6, axis=0) for k, v in m.face_fields.items()})  # 6 per input face
            run.metrics["subdivision_vertices"] = len(res.V)
        else:
            out = m.copy()
            out.vertex_fields[name] = g
            out.vertex_fields[f"{name}_original"] = f
        run.write_mesh(output, out)
        if critical is not None:
            doc = {"field": name, "threshold": threshold,
                   "euler_characteristic": summary.metrics["euler_characteristic"],
                   "before": critical_cells_table(res.cx, before, res.order),
                   "after": critical_cells_table(summary.cx_after, after, summary.order_after)}
            if barycentric:  # which mesh cell each subdivision vertex stands for
                for row in doc["after"]:
                    row["mesh_cell"] = mesh_cell(res, m.F, row["vertex"])
            run.write_bytes(critical, json_bytes(doc))
        if diagram is not None:
            with run.timer("diagram"):
                png = persistence_diagram_png(before, after, threshold,
                                              title=f"{os.path.basename(mesh)}: {name}, P = {threshold:.4g}")
            run.write_bytes(diagram, png)


def register(app: typer.Typer) -> None:
    """Add ``morse-simplify`` to the application."""
    app.command("morse-simplify", epilog=metrics_epilog(METRICS, units=METRIC_UNITS))(morse_simplify)


def _split_fans(run, m: Mesh, mesh: str) -> tuple[Mesh, np.ndarray | None]:
    """``m`` with one vertex per fan of faces, its fields carried and
    ``input_vertex`` added, and the input vertex of each vertex; ``m`` itself
    and None when every vertex has one fan (a note says so)."""
    from geoproc.mesh.clean import split_nonmanifold_vertices

    V, F, source = split_nonmanifold_vertices(m.V, m.F)
    path = m.log.path or mesh
    if len(V) == len(m.V):
        run.note(f"{path}: no vertex joins separate fans of faces; --split-nonmanifold changed nothing and "
                 "adds no input_vertex property")
        return m, None
    run.note_replaced("vertex", ["input_vertex"], m.vertex_fields)
    split = len(np.unique(source[len(m.V):]))
    run.note(f"{path}: split {split} non-manifold {'vertex' if split == 1 else 'vertices'} into "
             f"{split + len(V) - len(m.V)} (one per fan of "
             f"faces; {len(V)} vertices in all): the output's vertex ids are the split mesh's, and its "
             "input_vertex property gives each one's input vertex")
    fields = {k: v[source] for k, v in m.vertex_fields.items()}
    fields["input_vertex"] = source.astype(np.int32 if len(m.V) < 2**31 else np.int64)
    return Mesh(V, F, fields, dict(m.face_fields), m.log), source


def _beyond_note(beyond: int, threshold: float, max_change: float, summary, tie_rounding: float) -> str:
    """The note on vertices moved past P/2: where cancelled basins and peaks
    interact, or where breaking g's ties took more than units in the last
    place (the field's doubles too coarse for its values)."""
    head = f"{beyond} vertices moved by more than P/2 = {threshold / 2:.6g} (max |f - g| = {max_change:.6g})"
    f = summary.f_ref if summary.order_after is None else summary.f_ref[summary.order_after]  # the surface's
    spacing = float(np.spacing(np.abs(f).max())) if len(f) else 0.0
    if summary.tie_rise <= tie_rounding * threshold / 2 + 64 * spacing:  # within what counts as rounding
        return (f"{head} where cancelled basins and peaks interact; the critical points are still exactly the kept "
                "ones (--barycentric stays within P/2 on the barycentric subdivision, up to the doubles' rounding)")
    span = float(np.ptp(f)) + threshold
    crowded = span < spacing * len(f)
    why = (f"its {len(f)} values are more than the {span / spacing:.3g} doubles within their range" if crowded
           else "ties take one unit in the last place per tied value")
    return (f"{head}: g has no ties, and the doubles near the field's largest value are {spacing:.3g} apart "
            f"({why}), so breaking the ties moved values by up to {summary.tie_rise:.3g}; subtract a constant "
            "from the field (its mean, say) and run again")
