"""``geoproc info``: counts, topology and sizes of a mesh or point cloud."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from rich.table import Table
from rich.text import Text

from geoproc.animation import is_animation_path
from geoproc.report import json_safe
from geoproc_cli.common import (
    LOAD_METRICS,
    CheckOpt,
    DebugOpt,
    NoCleanOpt,
    QuietOpt,
    ReportOpt,
    command_run,
    escaped,
    flag,
    input_kind_needs,
    load_summary,
    metrics_epilog,
    refuse_options,
    stdout,
)

METRICS = LOAD_METRICS + (
    "vertices", "faces", "point_cloud", "duplicate_vertices", "bbox_diagonal", "edges", "components",
    "boundary_edges", "boundary_loops", "euler_characteristic", "genus", "closed", "edge_manifold",
    "vertex_manifold", "orientable", "consistently_oriented", "nonmanifold_edges", "nonmanifold_vertices",
    "degenerate_faces", "duplicate_faces", "unreferenced_vertices", "mean_edge_length", "frames", "worst_frame",
)
"""Every metric ``info`` reports (the scalar entries of :func:`geoproc.mesh.mesh_info`; ``frames``
and ``worst_frame`` for an animation, whose other entries are its first frame's but for the
degenerate faces and duplicate vertices, each the most of any frame)."""


def info(
    ctx: typer.Context,
    mesh: Annotated[str, typer.Argument(help="Mesh or point cloud: .obj, .ply, .off, .stl, or - for stdin; or "
                                        "an animation (.npz with 'vertices' (frames, n, 3) and 'faces', or a "
                                        "folder of frame meshes): its frame count, and its first frame's "
                                        "summary (the connectivity is every frame's).", metavar="MESH")],
    as_json: Annotated[bool, flag("--json", help="Print the summary as one JSON object on stdout.")] = False,
    no_clean: NoCleanOpt = False,
    report: ReportOpt = None,
    check: CheckOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Summarize a mesh: counts, topology, manifoldness, sizes.

    Prints vertices, faces, edges, components, boundary loops, Euler characteristic,
    genus, manifold and orientation flags, degenerate/duplicate/unreferenced counts,
    mean edge length and bounding-box diagonal (in the file's length unit).

    Genus is given only for closed, orientable, edge- and vertex-manifold meshes
    (summed over components); otherwise null. Every numeric entry is a metric for
    --check, e.g. --check 'genus==0'.
    """
    params = {"mesh": mesh, "json": as_json, "clean": not no_clean}
    animation = mesh != "-" and is_animation_path(mesh)
    if animation:
        params["clean"] = None  # frames are read as stored (as perturb and denoise report it)
    # a check on what only the other kind of input reports is refused before the input is read,
    # as perturb refuses it (it had been refused after the run, without the reason)
    needs = input_kind_needs(animation, ("frames", "worst_frame"))
    with command_run("info", params, report=report, checks=check, quiet=quiet, debug=debug,
                     outputs=["-"], inputs=[mesh], metrics=METRICS, needs=needs) as run:  # the summary goes to stdout
        frames = None
        if animation:
            if no_clean:
                refuse_options(ctx, ("no_clean",), "not used for an animation (frames are read as stored)")
            from geoproc.mesh.mesh import LoadLog, Mesh

            anim = run.load_animation(mesh)
            frames = anim.n_frames
            m = Mesh(anim.V[0], anim.F, {k: v[0] for k, v in anim.fields.items()},
                     log=LoadLog(path=mesh, unread_properties=list(anim.unread)))
        else:
            m = run.load_mesh(mesh, clean=not no_clean)
        from geoproc.mesh.info import mesh_info, worst_frame_counts  # (the kernels load once the mesh is read)

        with run.timer("compute"):
            summary = mesh_info(m)
        if frames is None:
            summary["load"] = load_summary(m.log)
        else:  # before the first frame's entries, which it qualifies
            summary = {"frames": frames, **summary, **worst_frame_counts(anim.V, anim.F)}
        run.metrics.update({k: v for k, v in summary.items() if not isinstance(v, list | dict)})
        if as_json:
            run.write_stdout((json.dumps(json_safe(summary), indent=2) + "\n").encode())
        else:
            with stdout.capture() as text:
                stdout.print(_table(mesh, summary))
            run.write_stdout(text.get().encode("utf-8", "surrogateescape"))  # undecodable file names as given


def _table(name: str, s: dict) -> Table:
    # names come from the file (its name, property names): never read as markup, and what is not
    # printable escaped as errors and notes escape it (a newline or an escape sequence in a file or
    # property name reached the terminal)
    t = Table(title=Text(escaped(name)), show_header=False, title_justify="left")
    t.add_column("key", style="bold")
    t.add_column("value", justify="right")
    for k, v in s.items():
        if k == "load":
            continue
        if isinstance(v, float):
            v = f"{v:.6g}"
        elif isinstance(v, list):
            v = ", ".join(v) if v else "-"
        elif v is None:
            v = "-"
        t.add_row(Text(k), Text(escaped(str(v))))
    return t


def register(app: typer.Typer) -> None:
    """Add ``info`` to the application."""
    app.command("info", epilog=metrics_epilog(METRICS))(info)
