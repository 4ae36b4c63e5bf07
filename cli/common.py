"""The command-line contract shared by every subcommand.

A subcommand declares the shared options with the ``*Opt`` aliases below and
runs its body inside :func:`command_run`::

    with command_run("info", params, report=report, checks=check,
                     quiet=quiet, debug=debug) as run:
        mesh = run.load_mesh(path, clean=not no_clean)
        with run.timer("compute"):
            ...
        run.metrics.update(...)
        run.write_mesh(output, mesh)

``command_run`` turns errors into exit codes (2 for bad input or usage, with a
one-line ``error: <file>: <problem>`` and no traceback unless ``--debug``),
defers every output file until the body succeeded and the checks are known to
be valid (so a failed run leaves nothing behind), writes the report, and
evaluates ``--check`` gates (exit 1 on a miss).
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import stat
import sys
import time
import traceback
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from typing import Annotated, TypeVar

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from geoproc.c_output import c_stdout_silenced
from geoproc.errors import GeoprocError, InputError, UsageError
from geoproc.fileio import file_kind, folder_of, read_input_bytes, sha256_bytes, sha256_file, write_files_atomic
from geoproc.mesh import Mesh, load_mesh, mesh_to_bytes
from geoproc.mesh.write import STL_MAX_COORDINATE, write_format
from geoproc.report import build_report, check_records, evaluate_checks, parse_check, require_known_metrics
from geoproc.report.report import report_json
from geoproc_cli.entry import interruption_cause, interruption_line, outputs_committed

EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3
T = TypeVar("T")
ONE_STDIN = "standard input can feed only one input; give the others as files"


class _StderrConsole(Console):
    """The stderr console. On a closed pipe rich exits 1 (and sends stdout to
    /dev/null); here the lines are dropped and the run keeps its exit code."""

    def on_broken_pipe(self) -> None:
        self.quiet = True


stderr = _StderrConsole(stderr=True, highlight=False, soft_wrap=True)
stdout = Console(highlight=False, soft_wrap=True)


def flag(*names: str, help: str, **options):
    """The typer option of a boolean flag, its value column in ``--help`` left
    empty: typer shows ``<bool>`` there, as if the flag took a value."""
    return typer.Option(*names, help=help, metavar="", **options)


ReportOpt = Annotated[
    str | None,
    typer.Option("--report", help="Write a JSON metric report here (schema: geoproc/report/report.schema.json); "
                 "- writes it to standard output.",
                 metavar="FILE.json", show_default=False),
]
CheckOpt = Annotated[
    list[str] | None,
    typer.Option("--check", help="Gate on one of the metrics listed below, as 'METRIC<=VALUE' (operators <=, <, "
                 ">=, >, ==, !=); repeatable; exit 1 when any fails.", metavar="'METRIC<=VALUE'", show_default=False),
]
QuietOpt = Annotated[bool, flag("--quiet", "-q", help="No progress bar or notes on stderr.")]
DebugOpt = Annotated[bool, flag("--debug", help="Show the full traceback on errors.")]
NoCleanOpt = Annotated[
    bool,
    flag("--no-clean", help="Keep the mesh as stored: do not merge coincident vertices "
         "or drop unreferenced ones."),
]


def escaped(text: str) -> str:
    """``text`` with every character that is not printable (control characters,
    line separators, undecodable bytes held as surrogates) written as its
    Python escape: ``\\n``, ``\\x1b``, ``\\udcff``."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


def say(line: str) -> None:
    """Print one line on stderr, control characters and undecodable bytes (e.g.
    in file names) escaped as \\n, \\udcff: each error, note or check line is
    one record (a note naming ``two\\nlines.obj`` had printed two lines). A
    stderr that cannot be written (a closed pipe, a full disk) loses the line
    but not the exit code: the run's outcome is its outputs and its status, and
    a write error here would turn both into exit 1."""
    line = escaped(line)
    try:
        stderr.print(line, markup=False)
    except OSError:
        pass


def _fail(message: str, code: int) -> typer.Exit:
    """Print ``error: <message>`` as one line (see :func:`say`) and return the exit."""
    say(f"error: {message}")
    return typer.Exit(code)


_LOAD_LOG_FIELDS = {"input_vertices": "stored_vertices", "input_faces": "stored_faces",
                    "triangulated_polygons": "triangulated_polygons", "merged_vertices": "merged_vertices",
                    "removed_unreferenced_vertices": "removed_unreferenced"}
LOAD_METRICS = tuple(_LOAD_LOG_FIELDS)
"""The metrics of every run that loads a mesh: what was stored in the file and
what loading changed (:meth:`Run.note_load`)."""


_LOAD_LOG_FOR_MESSAGES = ("collapsed_faces", "first_collapsed_face")  # named in refusals, not reported


def load_summary(log) -> dict:
    """A mesh's load log as a dict, its counts named as the report's :data:`LOAD_METRICS`
    (what only messages use left out)."""
    names = {field: metric for metric, field in _LOAD_LOG_FIELDS.items()}
    return {names.get(k, k): v for k, v in log.as_dict().items() if k not in _LOAD_LOG_FOR_MESSAGES}


def metrics_epilog(names: Sequence[str], text: Sequence[str] = (), units: dict[str, str] | None = None) -> str:
    """The closing paragraph of a subcommand's ``--help``: the metric names
    ``--check`` accepts, then those of ``names`` that are ``text`` (reported,
    not checked), then the units of those whose name does not tell (``units``:
    name to unit)."""
    numbers = sorted(n for n in names if n not in text)
    out = ("Metrics for --check and the report (some only with the options that produce them): "
           + ", ".join(numbers) + ".")
    out += " Text in the report: " + ", ".join(sorted(text)) + "." if text else ""
    return out + (" Units: " + "; ".join(f"{k} {v}" for k, v in units.items()) + "." if units else "")


class Run:
    """State of one subcommand run: inputs, params, metrics, timings, outputs."""

    def __init__(self, command: str, params: dict, quiet: bool):
        self.command = command
        self.params = params
        self.quiet = quiet
        self.inputs: list[dict] = []
        self.metrics: dict = {}
        self.timings: dict[str, float] = {}
        self._outputs: list[tuple[str, bytes]] = []
        self._frame_folders: list[tuple[str, list[str]]] = []  # (folder, frame file names written there)
        self._notes: list[str] = []
        self._stdin_read = False
        self._t0 = time.perf_counter()
        self.checked: set[str] = set()  # the metrics the run's --check gates name

    def refuse_unmeasurable_checks(self, names: tuple[str, ...], why: str) -> None:
        """UsageError, before the work, when a --check names one of the metrics
        ``names`` that this input cannot give; ``why`` says so (``"FILE: has
        no 'outlier' property"``). Checks are otherwise judged after the run."""
        missed = [n for n in names if n in self.checked]
        if missed:
            raise UsageError(f"--check on {', '.join(missed)}: {why}")

    # ---- inputs ---------------------------------------------------------
    def add_input(self, path: str | os.PathLike, data: bytes | None = None, digest: str = "") -> None:
        """Record an input file (or ``-``) with its SHA-256 for the report: of
        ``data``, or the ``digest`` of the bytes the reader parsed, else of the
        file read again."""
        name = os.fspath(path)
        if not digest:
            digest = sha256_bytes(data) if data is not None else sha256_file(name)
        self.inputs.append({"path": name, "sha256": digest})

    @staticmethod
    def one_stdin(*paths) -> None:
        """UsageError when more than one of the input ``paths`` is ``-``; checked
        before any is read, so that the error does not depend on what stdin holds."""
        if sum(os.fspath(p) == "-" for p in paths if p is not None) > 1:
            raise UsageError(ONE_STDIN)

    def read_stdin(self) -> bytes:
        """All of standard input (one input per run may be ``-``: a second is a
        UsageError)."""
        if self._stdin_read:
            raise UsageError(ONE_STDIN)
        self._stdin_read = True
        if sys.stdin is None:
            raise InputError("-", "standard input is closed")
        return sys.stdin.buffer.read()

    def read_input(self, path: str | os.PathLike, read: Callable[[str, bytes | None], T],
                   what: str | None = None) -> T:
        """``read(path, data)``, then the input recorded for the report.

        ``data`` is standard input's bytes when the path is ``-``; with ``what``
        (the kind of file, for the error when it is missing) the file's bytes,
        read here once, so that the recorded hash is that of the bytes parsed
        (a pipe such as ``<(seq 0 9)`` cannot be read twice); else None, and
        the reader opens the file itself.
        """
        name = os.fspath(path)
        data = self.read_stdin() if name == "-" else read_input_bytes(name, what) if what else None
        out = read(name, data)
        # a mesh carries the hash of the bytes it was parsed from: the file is
        # not read twice (it may have changed since, or be a pipe)
        self.add_input(name, data, getattr(getattr(out, "log", None), "sha256", ""))
        return out

    def load_mesh(self, path: str | os.PathLike, clean: bool = True, mesh_output: str | None = None) -> Mesh:
        """Read a mesh or point cloud (``-`` reads standard input) and record it.

        ``mesh_output``: the run's mesh output, whose extension is checked
        before the input is read, so that a mistyped one fails before the work
        (a ``.npz`` passes that check when the input is standard input, whose
        reading then says that an animation cannot come from there), and again
        once the input is read as a mesh (:func:`require_mesh_output`)."""
        stdin = os.fspath(path) == "-"
        if mesh_output is not None:
            require_mesh_output(mesh_output, allow_npz=stdin)
        with self.timer("load"):
            mesh = self.read_input(path, lambda name, data: load_mesh(name, clean=clean, stdin_bytes=data))
        if mesh_output is not None and stdin:
            require_mesh_output(mesh_output)
        self.note_load(mesh)
        return mesh

    def load_animation(self, path: str | os.PathLike, output: str | None = None):
        """Read an animation (``.npz``, or a folder of frame meshes with equal
        connectivity) under the ``load`` timer and record it as an input with the
        hash of the bytes parsed (a folder's covers its frame files' names and contents).
        With ``output``, the animation output it becomes: a folder of frames
        there refuses, before the work, a field no PLY property can carry."""
        from geoproc.animation import load_animation, names_folder, unwritable_frame_fields

        name = os.fspath(path)
        with self.timer("load"):
            anim = load_animation(name)
            self.add_input(name, digest=anim.sha256)
            if anim.frame_files:  # the frames in the order read, each checkable with sha256sum
                self.inputs[-1]["frames"] = [{"path": f, "sha256": h}
                                             for f, h in zip(anim.frame_files, anim.frame_sha256, strict=True)]
        bad = unwritable_frame_fields(anim) if output is not None and names_folder(output) else []
        if bad:
            raise UsageError(_unwritable_field_line(output, bad[0]))
        if anim.unread:
            self.inputs[-1]["not_carried"] = list(anim.unread)
            travel = ("per-vertex scalar properties of every frame" if anim.frame_files
                      else "real numeric arrays shaped (frames, n)")
            self.note(f"{name}: not carried (only {travel} travel): " + ", ".join(anim.unread))
        return anim

    def note_load(self, mesh: Mesh) -> None:
        """Put the read/clean-up log into the metrics (:data:`LOAD_METRICS`) and tell the user on stderr."""
        log = mesh.log
        summary = load_summary(log)
        self.metrics.update({k: summary[k] for k in LOAD_METRICS})
        notes = []
        if log.triangulated_polygons:
            notes.append(f"triangulated {log.triangulated_polygons} polygons")
        if log.merged_vertices:
            notes.append(f"merged {log.merged_vertices} coincident vertices")
        if log.removed_unreferenced:
            notes.append(f"dropped {log.removed_unreferenced} unreferenced vertices")
        if notes:
            self.note(f"{log.path}: " + ", ".join(notes) + " (--no-clean keeps the mesh as stored)"
                      if log.merged_vertices or log.removed_unreferenced else f"{log.path}: " + ", ".join(notes))
        if log.unread_properties:
            entry = next((e for e in reversed(self.inputs) if e["path"] == log.path), None)
            if entry is not None:  # in the report too: a note is silenced by --quiet
                entry["not_carried"] = list(log.unread_properties)
            travel = ("only scalar PLY properties travel" if log.format == "ply"
                      else f"only positions and faces are read from {log.format.upper()}")
            self.note(f"{log.path}: not carried ({travel}): " + ", ".join(log.unread_properties))

    def note_replaced(self, kind: str, names, existing) -> None:
        """Note the input's ``kind`` ("vertex" or "face") properties among ``names``
        (those found in ``existing``) that the output replaces."""
        clobbered = [k for k in names if k in existing]
        if clobbered:
            self.note(f"replacing the input's {kind} propert" + ("y " if len(clobbered) == 1 else "ies ")
                      + ", ".join(f"'{k}'" for k in clobbered))

    def outlier_flags(self, values, shape: tuple, path: str, frame_files: list[str] | None = None,
                      rewritten: bool = False) -> np.ndarray:
        """An ``outlier`` property read as flags (``geoproc.perturb.outlier_flags``:
        bool, of ``shape``), with a note when it holds values other than 0 and 1
        (interpolated by ``morse-simplify --barycentric``, say), which are read
        as flags where above 0.5 (``rewritten``: and the output writes them as 0
        and 1). ``denoise --outliers`` had scored against such values without a
        word, where ``perturb`` noted them."""
        from geoproc.perturb import outlier_flags

        flags = outlier_flags(values, shape, path, frame_files)
        other = int(np.count_nonzero((values != 0) & (values != 1)))
        if other:
            self.note(f"{path}: the 'outlier' property has {other} values other than 0 and 1: read as outlier "
                      "flags where above 0.5" + (", and written as 0 and 1" if rewritten else ""))
        return flags

    def note_kept_seams(self, mesh: Mesh, name: str) -> None:
        """Under --no-clean, a note when vertices the faces use share a position:
        each copy moves on its own, so the surface can open along those seams
        (denoise and perturb, which had opened them without a word)."""
        from geoproc.mesh.clean import repeated_positions
        from geoproc.mesh.topology import referenced_vertices

        copies = repeated_positions(mesh.V[referenced_vertices(mesh.F, len(mesh.V))])
        if copies:
            one = copies == 1
            self.note(f"{name}: {copies} {'vertex' if one else 'vertices'} the faces use "
                      f"repeat{'s' if one else ''} the position of another, and --no-clean keeps them apart: each "
                      "moves on its own, so the surface can open along those seams (without --no-clean they are "
                      "merged)")

    def refresh_normals(self, V, F, fields: dict) -> None:
        """Recompute the stored vertex normals (``nx``, ``ny``, ``nz``) among the
        per-vertex ``fields`` for the positions ``V`` the command moved the
        vertices to, in place, with a note (they had been carried unchanged: a
        perturbed bunny kept 764 of 3,485 normals more than 20 degrees off its
        own). See :func:`geoproc.mesh.normal_fields.refresh_normal_fields`."""
        from geoproc.mesh.normal_fields import refresh_normal_fields

        if refresh_normal_fields(V, F, fields):
            self.note("recomputed the vertex normals (nx, ny, nz) for the new positions")

    def note(self, text: str) -> None:
        """A one-line remark for stderr (silenced by --quiet), shown when the run
        ends without an error, so that a failed run prints its error line alone."""
        if not self.quiet:
            self._notes.append(text)

    def _flush_notes(self) -> None:
        for text in self._notes:
            say(f"note: {text}")
        self._notes.clear()

    # ---- timing and progress -------------------------------------------
    @contextlib.contextmanager
    def timer(self, name: str) -> Iterator[None]:
        """Accumulate wall-clock seconds under ``timings_s[name]``."""
        t = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - t

    @contextlib.contextmanager
    def progress(self, description: str, total: float = 1.0) -> Iterator[Callable[[float], None]]:
        """A rich progress bar on stderr; yields ``update(done)`` with done in [0, total].

        Nothing is drawn with --quiet or when stderr is not a terminal.
        """
        if self.quiet or not stderr.is_terminal:
            yield lambda done: None
            return
        bar = Progress(
            TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
            TimeElapsedColumn(), TimeRemainingColumn(), console=stderr, transient=True,
        )
        with bar:
            task = bar.add_task(description, total=total)
            yield lambda done: bar.update(task, completed=done)

    # ---- outputs ---------------------------------------------------------
    def write_bytes(self, path: str | os.PathLike, data: bytes) -> None:
        """Queue an output file; written atomically only when the run succeeds."""
        self._outputs.append((os.fspath(path), data))

    def write_mesh(self, path: str | os.PathLike, mesh: Mesh, ascii: bool = False) -> None:
        """Queue a mesh output: ``-`` is binary PLY on stdout, else by extension."""
        name = os.fspath(path)
        if name == "-":
            self._outputs.append(("-", mesh_to_bytes(mesh, "ply", binary=True)))
            return
        ext = write_format(name)
        if len(mesh.F) == 0 and ext != "ply":
            raise UsageError(f"{name}: a point cloud (no faces) is written as .ply only")
        dropped = ([f"vertex {k}" for k in mesh.vertex_fields] + [f"face {k}" for k in mesh.face_fields]
                   if ext != "ply" else [])
        if dropped:
            self.note(f"{name}: .{ext} keeps geometry only; not written: {', '.join(dropped)} "
                      "(a .ply output keeps them)")
        big = float(np.abs(mesh.V).max()) if ext == "stl" and mesh.V.size else 0.0
        if big > STL_MAX_COORDINATE:
            raise UsageError(f"{name}: STL stores 32-bit floats, which end at {STL_MAX_COORDINATE:.4g}; "
                             f"coordinates reach {big:.3g} (write .ply, .obj or .off)")
        if ext == "stl" and len(mesh.F):
            self._note_stl_changes(name, mesh)
        self._outputs.append((name, mesh_to_bytes(mesh, ext, binary=not ascii)))

    def _note_stl_changes(self, name: str, mesh: Mesh) -> None:
        """A note on what an STL output changes when read back: each triangle's
        corners as 32-bit floats (positions rounded, where they are not float32
        already) and the vertices numbered by their first use in the triangles
        (where that is not already their order, or a vertex is unused)."""
        V, F = mesh.V, mesh.F
        rounded = bool((V.astype(np.float32).astype(np.float64) != V).any())
        _, first = np.unique(F.reshape(-1), return_index=True)
        in_order = len(first) == len(V) and bool((np.diff(first) > 0).all())
        changes = (["positions rounded (to about 6e-8 of their size)"] * rounded
                   + ["vertices numbered anew (in order of first use)"] * (not in_order))
        if changes:
            self.note(f"{name}: STL stores each triangle's corners as 32-bit floats; read back: "
                      f"{' and '.join(changes)} (a .ply output keeps them)")

    def write_animation(self, path: str, anim) -> None:
        """Queue an animation output: a folder of frames when ``path`` names a
        folder (:meth:`write_frames`), else a ``.npz`` file (see
        :func:`require_animation_output`)."""
        from geoproc.animation import animation_to_bytes, names_folder

        require_animation_output(path)
        if names_folder(path):
            self.write_frames(path, anim)
        else:
            self.write_bytes(path, animation_to_bytes(anim))

    def write_frames(self, folder: str, anim) -> None:
        """Queue an animation as a folder of binary PLY frames, ``frame_0000.ply``
        and on (see :func:`geoproc.animation.animation_to_frames`), written with
        the other outputs: the folder is made when the run succeeds, and the
        ``frame_N.ply`` files an earlier run left there beyond these are removed
        once these are in place."""
        from geoproc.animation import animation_to_frames, unwritable_frame_fields

        bad = unwritable_frame_fields(anim)
        if bad:
            raise UsageError(_unwritable_field_line(folder, bad[0]))
        frames = animation_to_frames(anim)
        self._frame_folders.append((folder, [name for name, _ in frames]))
        self._outputs += [(os.path.join(folder, name), data) for name, data in frames]

    def write_stdout(self, data: bytes) -> None:
        """Queue bytes for standard output; written only when the run succeeds."""
        self._outputs.append(("-", data))

    def _commit(self, report: str | None, checks: list[dict] | None = None) -> None:
        """Write every queued output and the report (with ``checks``, the
        ``--check`` outcomes), all or none.

        The files are staged beside their destinations, standard output gets
        its bytes, and only then are the files renamed into place (so an
        unwritable report, or a full or closed standard output, leaves no file
        behind). A folder of frames is made first and removed again if the
        writing fails; an earlier run's other frame_N.ply files there are
        hidden just before the renames (put back if the writing fails) and
        removed after them.
        """
        folders = [folder for folder, _ in self._frame_folders]
        _require_frame_folders(folders, [i["path"] for i in self.inputs])
        created: list[str] = []  # the frame folders this run made, removed again if it fails
        hidden: list[tuple[str, str]] = []  # an earlier run's extra frames, hidden until the new ones are in

        def before_rename() -> None:
            _hide_stale_frames(self._frame_folders, hidden)
            if piped:
                _write_stdout(piped)

        try:
            _make_folders(folders, created)
            _require_output_folders([name for name, _ in self._outputs])
            self.timings["total"] = time.perf_counter() - self._t0
            outputs = list(self._outputs)
            if report is not None:
                rep = build_report(self.command, self.inputs, self.params, self.metrics, self.timings, checks)
                outputs.append((os.fspath(report), report_json(rep).encode()))
            _require_distinct_outputs([name for name, _ in outputs], [i["path"] for i in self.inputs], report)
            piped = b"".join(data for name, data in outputs if name == "-")
            try:
                write_files_atomic([(name, data) for name, data in outputs if name != "-"],
                                   before_rename=before_rename)
            except OSError as exc:
                name = exc.filename or "output"
                raise UsageError(f"{name}: cannot write: {exc.strerror or exc}") from None
        except BaseException:
            _restore_frames(hidden)
            for folder in reversed(created):  # no empty output folder is left behind
                with contextlib.suppress(OSError):
                    os.rmdir(folder)
            raise
        outputs_committed()  # in place: a signal from here would only misreport the run
        _drop_frames(hidden)


def _stray_stdout_dropped() -> contextlib.AbstractContextManager:
    """While a run that writes its result to standard output works, whatever
    else reaches file descriptor 1 (a compiled library's own prints) is
    discarded: the result must be all that standard output gets. (Sent to
    standard error instead, such lines could fail a run whose standard error
    is full.) The result itself is written after this, at commit."""
    if sys.__stdout__ is None or _stdout_identity() is None:
        return contextlib.nullcontext()  # a closed standard output: nothing to keep clean
    return c_stdout_silenced()


def _stdout_identity() -> tuple[int, int] | None:
    """(device, inode) of what file descriptor 1 is, or None when it is closed."""
    try:
        st = os.fstat(1)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _write_stdout(data: bytes) -> None:
    """Write ``data`` to standard output; OSError when it is closed or full."""
    if sys.stdout is None:
        raise OSError(errno.EBADF, "standard output is closed", "-")
    try:
        out = sys.stdout.buffer
        view = memoryview(data)
        while view:  # unbuffered (PYTHONUNBUFFERED) stdout is a raw file: writes may be partial
            n = out.write(view)
            if not n:  # a non-blocking descriptor that takes nothing
                raise OSError(errno.EAGAIN, "standard output accepts no more data", "-")
            view = view[n:]
        out.flush()
    except ValueError:  # a closed file object
        raise OSError(errno.EBADF, "standard output is closed", "-") from None


def _require_distinct_outputs(names: list[str], inputs: list[str], report: str | None) -> None:
    """Refuse two outputs on one path (standard output included, by ``-`` or by
    any name of the file or pipe it is, such as ``/dev/stdout`` or a link to
    it) and an output that would overwrite an input."""
    stdout_id = _stdout_identity()
    if stdout_id is not None and stdout_id == _file_id(os.devnull):
        stdout_id = None  # what goes to the null device cannot mix
    if sum(name == "-" or (stdout_id is not None and _file_id(name) == stdout_id) for name in names) > 1:
        what = "--report - and another output" if report is not None and os.fspath(report) == "-" \
            else "two outputs"
        raise UsageError(f"{what} both write to standard output; give all but one a file name")
    seen: set = set()
    inputs = list(inputs) + [f for p in inputs if p != "-" for f in _frame_files_of(p)]  # a folder's frames too
    sources = {os.path.realpath(p) for p in inputs if p != "-"}
    sources |= {_file_id(p) for p in inputs if p != "-"} - {None}  # hard links too
    if "-" in inputs:
        sources |= {_stdin_file_identity()} - {None}  # `- < out.ply` reads the file an output names
    for name in names:
        if name == "-":  # standard output redirected into an input (`-o - >> in.ply`)
            if stdout_id is not None and stdout_id in sources:
                raise UsageError("standard output (-) is also an input; write the result to another file")
            continue
        real, ident = os.path.realpath(name), _file_id(name)
        if ident is not None and ident == _file_id(os.devnull):
            continue  # what several outputs write there cannot mix
        if real in seen or (ident is not None and ident in seen):
            raise UsageError(f"{name}: given for two outputs; give each its own file name")
        if real in sources or (ident is not None and ident in sources):
            raise UsageError(f"{name}: is also an input; write the result to another file")
        seen |= {real, ident} - {None}


def _unwritable_field_line(folder: str, name: str) -> str:
    return (f"{folder}: field '{name}' cannot be a PLY vertex property of a frame (printable ASCII without "
            "spaces, other than x, y, z and end_header); write a .npz")


def _frame_files_of(path: str) -> list[str]:
    """The files a folder input is read from (as
    :func:`geoproc.animation.load_animation` takes them); [] for a file."""
    from geoproc.animation import frame_file_candidates

    try:
        return [os.path.join(path, f) for f in frame_file_candidates(path)] if os.path.isdir(path) else []
    except OSError:  # unreadable: reading it will say so
        return []


def _stdin_file_identity() -> tuple[int, int] | None:
    """(device, inode) of the regular file standard input reads, else None
    (a pipe, a terminal, closed)."""
    try:
        st = os.fstat(0)
    except OSError:
        return None
    return (st.st_dev, st.st_ino) if stat.S_ISREG(st.st_mode) else None


def _file_id(path: str) -> tuple[int, int] | None:
    """(device, inode) of an existing file (through symbolic links), else None:
    two names of one file (a hard link) share it."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino)


def _require_output_folders(names: list[str]) -> None:
    """Refuse an output that names a folder, or whose folder does not exist or
    cannot take a new file (for a symbolic link, the folder of its target,
    which is what is written; a device or FIFO, written directly, needs none)."""
    for name in names:
        if name == "-":
            continue
        if not name:  # realpath('') is the working folder: 'is a folder' would puzzle
            raise UsageError("an output file name is empty")
        real = os.path.realpath(name)
        if os.path.isdir(real):
            raise UsageError(f"{name}: cannot write: is a folder; give a file name")
        if name.endswith(("/", os.sep)):  # a folder's name, of a folder that is not there
            raise UsageError(f"{name}: cannot write: names a folder (it ends with '/'); give a file name")
        folder = os.path.dirname(real) if os.path.islink(name) else folder_of(name)
        if not os.path.isdir(folder):
            raise UsageError(f"{name}: output folder '{folder}' does not exist")
        if file_kind(name) == "other":  # written directly, as write_files_atomic does
            continue
        if not os.access(folder, os.W_OK | os.X_OK):  # read-only file system, no permission
            raise UsageError(f"{name}: cannot write: output folder '{folder}' is not writable")


def _require_frame_folders(folders: list[str], inputs: list[str]) -> None:
    """Refuse a frame-folder output that is not a folder, whose parent folder
    does not exist or cannot take it, that is an input, that holds mesh files
    other than ``frame_N.ply`` (read back as an animation, they would be taken
    for frames), or whose ``frame_N.ply`` entries are not plain files (a
    symbolic link, a pipe, a device or a folder: a frame written there would
    go elsewhere, or block)."""
    from geoproc.animation import frame_folder_problem

    sources = {os.path.realpath(p) for p in inputs if p != "-"}
    for folder in folders:
        real = os.path.realpath(folder)
        if os.path.dirname(real) == real:
            raise UsageError(f"{folder}: name a folder for the frames other than the root")
        if os.path.exists(real) and not os.path.isdir(real):
            raise UsageError(f"{folder}: cannot write the frames: is a file, not a folder")
        if real in sources:
            raise UsageError(f"{folder}: is also an input; write the frames to another folder")
        parent = os.path.dirname(real)
        if not os.path.isdir(real) and not os.path.isdir(parent):
            linked = os.path.islink(os.path.normpath(folder))  # a dangling link: its target's folder is missing
            shown = parent if linked else os.path.dirname(os.path.normpath(folder)) or "."
            raise UsageError(f"{folder}: output folder '{shown}' does not exist")
        where = real if os.path.isdir(real) else parent
        if not os.access(where, os.W_OK | os.X_OK):
            raise UsageError(f"{folder}: cannot write: folder '{where}' is not writable")
        problem = frame_folder_problem(real)
        if problem:
            raise UsageError(f"{folder}: {problem}")


def _make_folders(folders: list[str], made: list[str]) -> None:
    """Make the frame folders that are not there, appending each to ``made``
    as it is made (so that a failure can remove those made before it)."""
    for folder in folders:
        real = os.path.realpath(folder)
        if not os.path.isdir(real):
            try:
                os.mkdir(real)
            except OSError as exc:
                raise UsageError(f"{folder}: cannot make the folder: {exc.strerror or exc}") from None
            made.append(real)


def _hide_stale_frames(folders: list[tuple[str, list[str]]], hidden: list[tuple[str, str]]) -> None:
    """Rename the ``frame_N.ply`` files in each frame folder other than those
    this run writes there (an earlier run's, from a longer animation or with
    wider numbers), to hidden names (which no frame folder reads),
    appending (name, hidden name) to ``hidden`` as each is done, so that a
    failure can put them back (:func:`_restore_frames`)."""
    from geoproc.animation import stale_frame_files

    for folder, written in folders:
        real = os.path.realpath(folder)
        for name in stale_frame_files(real, written):
            full = os.path.join(real, name)
            hide = os.path.join(real, f".{name}.{os.getpid()}.stale")
            try:
                os.rename(full, hide)
            except OSError as exc:
                raise UsageError(f"{folder}: cannot remove the earlier run's {name}: {exc.strerror or exc}; "
                                 "nothing was written") from None
            hidden.append((full, hide))


def _restore_frames(hidden: list[tuple[str, str]]) -> None:
    """Put back the frames :func:`_hide_stale_frames` hid (a failed run)."""
    for full, hide in reversed(hidden):
        with contextlib.suppress(OSError):
            os.rename(hide, full)


def _drop_frames(hidden: list[tuple[str, str]]) -> None:
    """Remove the hidden earlier frames once the new ones are in place (one
    that cannot be removed stays hidden, unread as a frame)."""
    for _, hide in hidden:
        with contextlib.suppress(OSError):
            os.remove(hide)


def _require_finite_options(params: dict) -> None:
    """Refuse nan or inf in a numeric option (every float parameter is the
    option of the same name, ``sigma_r`` for ``--sigma-r``), naming it as typed
    (``1e400``, which reads as inf, had been named ``inf``), under the form
    typed (``-c 1e400`` is named ``-c``; see :data:`TYPED_OPTIONS`)."""
    for key, value in params.items():
        if isinstance(value, float) and not math.isfinite(value):
            name, typed = TYPED_OPTIONS.get(key, (f"--{key.replace('_', '-')}", None))
            shown = f"{escaped(typed)} (which reads as {value})" if typed and typed.lower() not in (
                str(value), f"+{value}", "infinity", "+infinity", "-infinity") else str(value)
            raise UsageError(f"{name} {shown}: must be a finite number")


TYPED_OPTIONS: dict[str, tuple[str, str]] = {}
"""For each single-value option of the running command given on the command
line, the form used (``--time-factor``, or ``-c`` when the long form was not
typed) and the text the parser read as its value, kept by the parser
(:func:`cli.main.command`): the text a scan of the arguments had found
missed option clusters (``-qc1e400``) and took another option's value
(``-o -c5.ply``) or a file after ``--`` for it."""


def choices_metavar(names: Sequence[str]) -> str:
    """How --help shows an option that takes one of ``names``: ``<a|b|c>``, as
    Typer shows the options typed as enumerations."""
    return "<" + "|".join(names) + ">"


def options_given(ctx: typer.Context, *names: str) -> list[str]:
    """The long flags (``--k``) of the parameters ``names`` (``k``) that the
    command line or the environment set, in the order given; defaults do not
    count. ``ctx`` is the command's context (a ``ctx: typer.Context`` parameter)."""
    flags = {p.name: max(p.opts, key=len) for p in ctx.command.params}
    given = ("COMMANDLINE", "ENVIRONMENT", "PROMPT")
    return [flags[n] for n in names if getattr(ctx.get_parameter_source(n), "name", None) in given]


def require_extension(path: str | os.PathLike, ext: str, option: str, stdout_ok: bool = False) -> None:
    """UsageError unless the file name ``path`` ends in ``ext`` (e.g. ``".png"``,
    any case); ``-`` (standard output) passes when ``stdout_ok``."""
    name = os.fspath(path)
    if not name:
        raise UsageError(f"{option}: the file name is empty")
    if (stdout_ok and name == "-") or name.lower().endswith(ext):
        return
    if file_kind(name) == "other":  # a device or FIFO, written to directly (/dev/null keeps only the report)
        return
    if name == "-":
        raise UsageError(f"{option} -: this file is not written to standard output; give a file name ending in {ext}")
    raise UsageError(f"{option} {name}: must end in {ext}" + (" (or be -)" if stdout_ok else ""))


def available_memory() -> int | None:
    """Bytes of memory the system can give without swapping (Linux's
    MemAvailable), or None where that is not known."""
    try:
        with open("/proc/meminfo", "rb") as fh:
            for line in fh:
                if line.startswith(b"MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def require_memory(needed: float, what: str) -> None:
    """MemoryError (reported as ``out of memory``, exit 2) when ``needed`` bytes,
    an estimate of what ``what`` takes, exceed the memory available: the
    kernel would otherwise kill the process with no error line."""
    free = available_memory()
    if free is not None and needed > free:
        raise MemoryError(f"{what} needs about {needed / 2**30:.3g} GiB, and {free / 2**30:.3g} GiB are available")


def require_mesh_output(output: str, allow_npz: bool = False) -> None:
    """UsageError unless the mesh output ``output`` is ``-`` or has an extension
    a mesh is written in (checked before the work, not after it). ``allow_npz``
    lets ``.npz`` pass, for a check before an input on standard input is read
    (which then says that an animation cannot come from there; once it is read
    as a mesh, the check is made again without it)."""
    from geoproc.fileio import file_extension
    from geoproc.mesh.write import write_format

    if output != "-" and not (allow_npz and file_extension(output) == "npz"):
        write_format(output)


def require_ply_output(output: str, what: str) -> None:
    """UsageError unless the mesh output ``output`` is ``-`` or a ``.ply``
    file: ``what`` says what only PLY keeps (``"the distance is a vertex
    property"``). A ``.npz`` name is told it holds animations (the writer's
    own message had offered OBJ, OFF and STL, which this refuses); a name
    without a mesh extension gets the writer's own message (no extension, or
    one it cannot write), not this one."""
    from geoproc.fileio import file_extension
    from geoproc.mesh.write import write_format

    ext = file_extension(output)
    if output == "-" or ext == "ply":
        return
    if ext == "npz":
        raise UsageError(f"{output}: .npz holds animations, and {what}, which only PLY keeps; use a .ply output")
    if write_format(output) == "ply":  # (raises for a name without a mesh format) a device: binary PLY
        return
    raise UsageError(f"{output}: {what}, which only PLY keeps; use a .ply output")


def require_animation_output(output: str) -> None:
    """UsageError unless ``output`` can take an animation: a ``.npz`` file, or
    a folder of frames (a name ending in ``/``, or an existing folder)."""
    from geoproc.animation import names_folder

    if not (names_folder(output) or output.lower().endswith(".npz")):
        raise UsageError(f"{output}: an animation is written as .npz or as a folder of frames (a name ending "
                         "in '/')")


def input_kind_needs(animation: bool, animation_metrics: tuple[str, ...]) -> dict[str, tuple[str, ...]]:
    """``command_run``'s ``needs`` for what only one kind of input reports: the
    load counts (:data:`LOAD_METRICS`) a mesh or point cloud's, the
    ``animation_metrics`` an animation's (perturb and info)."""
    if animation:
        return {"a mesh or point cloud (not an animation)": LOAD_METRICS}
    return {"an animation (.npz or a folder of frames)": animation_metrics}


def frame_folder_outputs(output: str, animation: bool) -> tuple[list[str], list[str]]:
    """``command_run``'s ``outputs`` and ``folders`` for a command whose one
    output is ``output``: a folder of frames when the input is an
    ``animation`` and ``output`` names a folder, else a file."""
    from geoproc.animation import names_folder

    return ([], [output]) if animation and names_folder(output) else ([output], [])


def refuse_options(ctx: typer.Context, names: tuple[str, ...], why: str) -> None:
    """UsageError when any parameter of ``names`` was given, e.g.
    ``refuse_options(ctx, ("k", "keep_all"), "only with --outliers")`` gives
    ``--k, --keep-all: only with --outliers``: an option that would be ignored
    is refused, not dropped silently."""
    given = options_given(ctx, *names)
    if given:
        raise UsageError(f"{', '.join(given)}: {why}")


@contextlib.contextmanager
def command_run(
    command: str,
    params: dict,
    *,
    report: str | None = None,
    checks: list[str] | None = None,
    quiet: bool = False,
    debug: bool = False,
    outputs: Sequence[str | os.PathLike | None] = (),
    folders: Sequence[str] = (),
    inputs: Sequence[str | os.PathLike | None] = (),
    metrics: Collection[str] | None = None,
    needs: Mapping[str, Collection[str]] | None = None,
    text_metrics: Collection[str] = (),
) -> Iterator[Run]:
    """Run a subcommand body under the command-line contract (see module doc).

    ``outputs`` (the output paths the options name, None for one not given)
    and ``inputs`` (the input paths) are checked before the body runs: every
    output folder exists, no two outputs share a path, and no output is an
    input. A mistyped output path then fails at once, not after the work;
    the outputs are checked again when they are written. ``folders`` are
    outputs that are folders of frames (see :meth:`Run.write_frames`), checked
    likewise before the body: each is a folder or can be made, is not an
    input, and holds no mesh file it would not write. ``metrics`` (every
    metric name the command can report) lets a ``--check`` on any other name
    fail at once as well, and so does ``needs`` (for each option not given,
    such as ``--reference``, the metrics only it reports) and ``text_metrics``
    (those among ``metrics`` whose values are text); whether this run reports
    the rest is judged after the body.

    Exit codes: 0 success, 1 a --check failed, 2 bad input or usage, 3 an
    internal error (a bug; --debug shows the traceback).
    """
    run = Run(command, dict(params), quiet)
    outputs_committed(False)  # a signal interrupts this command until its outputs are in place
    try:
        parsed = [parse_check(c) for c in (checks or [])]
        run.checked = {c.metric for c in parsed}
        if metrics is not None:
            require_known_metrics(parsed, metrics, command, needs, text_metrics)
        _require_finite_options(params)
        for key, value in run.params.items():  # -0 is 0 (perturb --noise -0 had been reported as -0.0)
            if isinstance(value, float) and value == 0.0:
                run.params[key] = 0.0
        if report is not None:
            require_extension(report, ".json", "--report", stdout_ok=True)
        made = {os.path.realpath(f) for f in folders}  # frame folders the run makes: a report may go there
        in_made = report is not None and os.fspath(report) != "-" and os.path.realpath(folder_of(report)) in made
        if report is not None and os.fspath(report) != "-" and not os.path.isdir(folder_of(report)) and not in_made:
            raise UsageError(f"--report {report}: output folder '{folder_of(report)}' does not exist")
        named = [os.fspath(p) for p in (*outputs, report) if p is not None]
        _require_output_folders([n for n in named if not (in_made and n == os.fspath(report))])
        _require_frame_folders(list(folders), [os.fspath(p) for p in inputs if p is not None])
        # a frame folder is an output too: a report of the same name would clash with it
        _require_distinct_outputs(named + [os.fspath(f) for f in folders],
                                  [os.fspath(p) for p in inputs if p is not None], report)
        with _stray_stdout_dropped() if "-" in named else contextlib.nullcontext():
            yield run
        # raises on unknown metric names; each line names the run's first input, as error lines name the file
        failures = evaluate_checks(parsed, run.metrics, run.inputs[0]["path"] if run.inputs else None)
        run._commit(report, check_records(parsed, run.metrics))
        outputs_committed()  # the run is done: a signal from here would only misreport it
        run._flush_notes()
    except typer.Exit:
        raise
    except InputError as exc:
        if debug:
            traceback.print_exc()
        raise _fail(exc.line(), EXIT_BAD_INPUT) from None
    except (UsageError, GeoprocError) as exc:
        if debug:
            traceback.print_exc()
        raise _fail(str(exc), EXIT_BAD_INPUT) from None
    except KeyboardInterrupt as exc:
        raise _fail(*interruption_line(exc)) from None
    except MemoryError as exc:  # a request too large for this machine (grid size, step count)
        if debug:
            traceback.print_exc()
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else "the request is too large"
        raise _fail(f"out of memory: {detail}", EXIT_BAD_INPUT) from None
    except Exception as exc:  # a bug: keep the one-line contract, offer the traceback
        stop = interruption_cause(exc)
        if stop is not None:  # Ctrl-C inside a compiled kernel comes back as a SystemError
            raise _fail(*interruption_line(stop)) from None
        if debug:
            traceback.print_exc()
        line = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise _fail(f"internal error: {type(exc).__name__}: {line} (rerun with --debug for the traceback)",
                    EXIT_INTERNAL) from None
    if failures:
        for line in failures:
            say(line)
        raise typer.Exit(EXIT_CHECK_FAILED)
