"""Read OBJ, PLY (ASCII and binary), OFF and STL files into a :class:`Mesh`.

PLY keeps every named scalar vertex and face property (positions as float64,
fields in their stored type; list properties are named in ``mesh.log.unread_properties``):
the usual layout (faces as index lists of one length) is read vectorized by
:mod:`geoproc.mesh.ply_uniform`, anything else by plyfile. OBJ and ASCII OFF
are parsed here, vectorized; STL goes through trimesh with
``process=False``. Polygons with more than three corners are triangulated as
fans and counted in
``mesh.log.triangulated_polygons``. After reading, the mesh is
validated (see :func:`validate_arrays`) and, unless ``clean=False``, cleaned by
:func:`geoproc.mesh.clean.clean_mesh`.
"""

from __future__ import annotations

import io
import logging
import os
import re
import warnings

import numpy as np

from geoproc.errors import InputError, first_line
from geoproc.fileio import file_extension, read_input_bytes, require_input_file, sha256_bytes
from geoproc.mesh.clean import clean_mesh
from geoproc.mesh.mesh import LoadLog, Mesh
from geoproc.mesh.ply_uniform import MAX_COUNT_DIGITS, parse_ply_header, read_uniform_ply, smallest_row_bytes
from geoproc.mesh.text_numbers import numbers_on_lines, uniform_rows
from geoproc.mesh.validate import require_indices_below

MESH_FORMATS = ("obj", "ply", "off", "stl")


def load_mesh(path: str | os.PathLike, clean: bool = True, stdin_bytes: bytes | None = None) -> Mesh:
    """Read a mesh or point cloud from ``path``.

    Parameters
    ----------
    path : str or PathLike
        A ``.obj``, ``.ply``, ``.off`` or ``.stl`` file (case-insensitive), or ``"-"``
        together with ``stdin_bytes`` (the format is then sniffed from the content).
    clean : bool
        Merge coincident positions and drop unreferenced vertices (default True).
    stdin_bytes : bytes, optional
        The content to parse when ``path`` is ``"-"``.

    Returns
    -------
    Mesh
        With ``mesh.log`` describing the file and the clean-up.

    Raises
    ------
    InputError
        Missing or unreadable file, unknown extension, unparseable content, no
        vertices, no faces (except a PLY point cloud), non-finite coordinates,
        face indices out of range.
    """
    name = str(path)
    if name == "-":
        if not stdin_bytes:
            raise InputError("-", "no data on standard input")
        data = stdin_bytes
        fmt = sniff_format(data, name)
    else:
        require_input_file(name, "mesh file")
        fmt = format_from_extension(name)
        data = read_input_bytes(name, "mesh file")
    return read_mesh_bytes(data, fmt, name, clean=clean)


def format_from_extension(path: str) -> str:
    """The mesh format named by the file extension, or InputError."""
    ext = file_extension(path)
    if ext not in MESH_FORMATS:
        shown = f"'.{ext}'" if ext else "no extension"
        raise InputError(path, f"unknown mesh format ({shown}); expected .obj, .ply, .off or .stl")
    return ext


def _text(raw: bytes) -> str:
    """File bytes quoted in a message: UTF-8 as written (they had been read as Latin-1,
    'é' shown as 'Ã©'), a byte that does not decode as its escape (``\\xff``)."""
    return raw.decode("utf-8", "backslashreplace")


_LEADING_COMMENTS = re.compile(rb"(\s*#[^\n]*\n)+")


def sniff_format(data: bytes, path: str = "-") -> str:
    """Guess the mesh format of raw bytes (for standard input)."""
    # a binary STL's length is exact; its 80-byte header is free text, which may start with
    # digits, 'ply' or 'OFF' (an exporter's name), so this comes first. Text in bytes 80-84
    # would declare over 500 million triangles, so no text file passes it
    if _binary_stl_triangles(data) is not None:
        return "stl"
    if data.startswith(b"PK\x03\x04"):  # a zip archive: an animation's .npz (its bytes can read as OBJ)
        raise InputError(path, "looks like a .npz animation; animations are read from a file or folder, "
                               "not from standard input")
    if data.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte order mark
        data = data[3:]
    # OFF and OBJ allow leading comments, as long as they like (a comment cut at byte 4096 had
    # been read as the first token, and an OBJ whose first keyword came after 64 KB not found)
    skipped = _LEADING_COMMENTS.match(data)
    start = skipped.end() if skipped else 0
    head = data[start:start + 4096].lstrip()
    if head.startswith(b"ply"):
        return "ply"
    first = head.split(None, 1)[0] if head.strip() else b""
    if _OFF_KEYWORD.fullmatch(first) or first.lower() == b"off":
        return "off"
    if re.match(rb"\d+[ \t]+\d+([ \t]+\d+)?[ \t]*(#[^\n]*)?\r?\n", head):  # OFF without its keyword
        return "off"
    if head[:5].lower() == b"solid" and b"facet" in data[:4096].lower():  # (upper case too, as by name)
        return "stl"
    if re.search(rb"^[ \t]*(v|vt|vn|vp|f|l|o|g|s|usemtl|mtllib)[ \t]", data[start:start + 65536], flags=re.M):
        return "obj"
    raise InputError(path, "cannot tell the mesh format of the data (not PLY, OFF, STL or OBJ)")


def read_mesh_bytes(data: bytes, fmt: str, path: str = "-", clean: bool = True) -> Mesh:
    """Parse ``data`` in format ``fmt`` (see :func:`load_mesh`)."""
    if len(data) == 0:
        raise InputError(path, "file is empty")
    digest = sha256_bytes(data)  # of the bytes as stored, as sha256sum gives it
    if data.startswith(b"\xef\xbb\xbf") and fmt in ("obj", "off"):  # a UTF-8 byte order mark
        data = data[3:]
    unread: list[str] = []
    if fmt == "ply":
        mesh, polys, unread = _parse_ply(data, path)
    elif fmt == "obj":
        mesh, polys, unread = _parse_obj(data, path)
    elif fmt == "off":
        mesh, polys, unread = _parse_off(data, path)
    else:
        mesh, polys = _parse_with_trimesh(data, fmt, path)
    mesh.log = LoadLog(
        path=path,
        format=fmt,
        stored_vertices=len(mesh.V),
        stored_faces=len(mesh.F),
        triangulated_polygons=polys,
        cleaned=clean,
        sha256=digest,
        unread_properties=unread,
    )
    validate_arrays(mesh.V, mesh.F, path, allow_point_cloud=(fmt == "ply"))
    if clean:
        mesh = clean_mesh(mesh)
    return mesh


MAX_COORDINATE = 1e50  # beyond, products of squared lengths (areas squared, cotangents) overflow float64
MIN_EXTENT = 1e-50  # below, squared areas underflow float64


def require_coordinates_in_range(V: np.ndarray, path: str) -> None:
    """Raise InputError when a finite coordinate of V (any shape, last axis the
    coordinates) exceeds :data:`MAX_COORDINATE` in magnitude, or when the points
    span less than :data:`MIN_EXTENT` without all coinciding: areas and their
    products would overflow or underflow float64. Rescale such inputs."""
    big = float(np.abs(V).max()) if V.size else 0.0
    if big > MAX_COORDINATE:
        raise InputError(path, f"coordinates as large as {big:.3g} overflow products of squared lengths "
                         f"(each must stay within +-{MAX_COORDINATE:.0e}; rescale the input)")
    P = V.reshape(-1, V.shape[-1]) if V.size else V
    span = (P.max(axis=0) - P.min(axis=0)) if V.size else np.zeros(1)
    top = float(np.abs(span).max())
    # the box diagonal, scaled by its largest side first: squared, a side of 1e-170 underflowed
    # to 0 and read as points that all coincide
    extent = top * float(np.linalg.norm(span / top)) if top > 0 else 0.0
    if 0.0 < extent < MIN_EXTENT:
        raise InputError(path, f"the points span only {extent:.3g}; areas underflow below an extent of "
                         f"{MIN_EXTENT:.0e} (rescale the input)")


def validate_arrays(V: np.ndarray, F: np.ndarray, path: str, allow_point_cloud: bool = False) -> None:
    """Raise InputError for an empty mesh, non-finite or overflowing positions
    (beyond :data:`MAX_COORDINATE`) or bad indices.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    path : str
        Named in the error.
    allow_point_cloud : bool
        Accept ``m == 0`` (a point cloud).
    """
    if len(V) == 0:
        raise InputError(path, "mesh has no vertices")
    if len(F) == 0 and not allow_point_cloud:
        raise InputError(path, "mesh has no faces (vertices only; store a point cloud as PLY)")
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise InputError(
            path, f"{int(bad.sum())} vertices have non-finite coordinates (first: vertex {first})"
        )
    require_coordinates_in_range(V, path)
    require_indices_below(F, len(V), path)


def _fan_triangulate(faces: list) -> tuple[np.ndarray, int]:
    """Split polygons (lists of vertex indices) into triangle fans.

    Returns the (m, 3) triangles and the number of polygons with more than three
    corners. Faces with fewer than three corners are rejected by the caller.
    """
    lengths = np.fromiter((len(f) for f in faces), dtype=np.int64, count=len(faces))
    if len(faces) and (lengths == 3).all():
        return np.asarray(np.stack(faces), dtype=np.int64).reshape(-1, 3), 0
    flat = np.concatenate([np.asarray(f, dtype=np.int64) for f in faces]) if faces else np.zeros(0, np.int64)
    return _fans(flat, lengths)


def _fans(idx: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, int]:
    """Triangle fans ``(p0, pk, pk+1)`` of polygons stored back to back in
    ``idx`` with ``counts`` corners each (all >= 3), vectorized; returns the
    (m, 3) triangles and the number of polygons with more than three corners."""
    start = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    per = counts - 2
    first = np.repeat(start, per)
    k = np.arange(int(per.sum())) - np.repeat(np.cumsum(per) - per, per) + 1
    tris = np.stack([idx[first], idx[first + k], idx[first + k + 1]], axis=1)
    return tris.astype(np.int64), int((counts > 3).sum())


def _scalar_property(dtype: np.dtype, name: str) -> bool:
    """Whether a PLY property can travel as a field: one number per row."""
    return dtype[name].shape == () and dtype[name].kind in "fiub"


def _field_dtype(stored: np.dtype) -> np.dtype:
    """The in-memory type of a PLY property read as a field: its stored type in
    native byte order (uchar colours stay uint8, a float stays float32), so that
    it is written back as stored."""
    return stored.newbyteorder("=")


def _parse_ply(data: bytes, path: str) -> tuple[Mesh, int, list[str]]:
    """The mesh, its polygon count (as :func:`_fans`) and the properties not read
    (see :attr:`geoproc.mesh.mesh.LoadLog.unread_properties`)."""
    data = _plain_ply_header(data)
    elements = read_uniform_ply(data)
    if elements is None:  # blank lines among ASCII rows: read without them
        unblank = _without_blank_ascii_rows(data)
        if unblank is not data:
            data, elements = unblank, read_uniform_ply(unblank)
    if elements is None:  # outside the vectorized layout: plyfile reads it, or names the problem
        header = _require_declared_rows_fit(data, path)
        try:
            elements = _plyfile_elements(data, path)
        except InputError:
            # text beyond the declared rows is the header's count, unless a row of the first
            # element is short: a row written over two lines, which plyfile names
            if not _first_element_has_a_short_row(data, header):
                _refuse_text_after_ascii_rows(data, path, header)
            raise
        _refuse_text_after_ascii_rows(data, path, header)
    if "vertex" not in elements:
        raise InputError(path, "PLY has no 'vertex' element")
    vert = elements["vertex"]
    for axis in "xyz":
        if axis not in vert.dtype.names:
            raise InputError(path, f"PLY vertex element has no '{axis}' property")
        if vert.dtype[axis].kind not in "fiu" or vert.dtype[axis].shape != ():
            raise InputError(path, f"PLY vertex property '{axis}' is not a number (a list?)")
    with np.errstate(invalid="ignore"):  # a signalling NaN stored as float32 widens quietly (refused below)
        V = np.column_stack([np.asarray(vert[a], dtype=np.float64) for a in "xyz"])
        vfields = {  # copies: the vectorized reader's rows are read-only views of the file's bytes
            n: np.array(vert[n], dtype=_field_dtype(vert.dtype[n]))
            for n in vert.dtype.names
            if n not in ("x", "y", "z") and _scalar_property(vert.dtype, n)
        }
    unread = [f"vertex {n}" for n in vert.dtype.names if n not in ("x", "y", "z") and n not in vfields]
    F = np.zeros((0, 3), dtype=np.int64)
    ffields: dict[str, np.ndarray] = {}
    polys = 0
    if "face" in elements and len(elements["face"]):
        fdata = elements["face"]
        key = next((k for k in ("vertex_indices", "vertex_index") if k in fdata.dtype.names), None)
        if key is None:
            raise InputError(path, "PLY face element has no 'vertex_indices' list")
        flat, counts = _index_lists(fdata, key, path)
        short = np.flatnonzero(counts < 3)
        if len(short):
            raise InputError(path, f"face {short[0]} has fewer than 3 corners")
        _require_integer_indices(flat, counts, path)
        if (counts == 3).all():
            F = flat.astype(np.int64).reshape(-1, 3)
        else:
            F, polys = _fans(flat.astype(np.int64), counts)
        with np.errstate(invalid="ignore"):
            ffields = {  # a polygon's values go to each triangle of its fan
                n: np.repeat(np.asarray(fdata[n], dtype=_field_dtype(fdata.dtype[n])), counts - 2)
                for n in fdata.dtype.names
                if n != key and _scalar_property(fdata.dtype, n)
            }
        unread += [f"face {n}" for n in fdata.dtype.names if n != key and n not in ffields]
    if "tristrips" in elements and len(elements["tristrips"]):
        sdata = elements["tristrips"]
        if "vertex_indices" not in sdata.dtype.names:
            raise InputError(path, "PLY tristrips element has no 'vertex_indices' list")
        flat, counts = _index_lists(sdata, "vertex_indices", path, "tristrips")
        _require_integer_indices(flat, counts, path, "tristrips row")
        F = np.concatenate([F, _strip_triangles(flat, counts)])
        unread += [f"tristrips {n}" for n in sdata.dtype.names if n != "vertex_indices"]
        unread += [f"face {n}" for n in ffields]
        ffields = {}  # per-face properties belong to the face element alone
    unread += [f"element {name}" for name, rows in elements.items()
               if name not in ("vertex", "face", "tristrips") and len(rows)]
    return Mesh(V, F, vfields, ffields), polys, unread


def _ply_header_end(data: bytes) -> re.Match | None:
    """The ``end_header`` line of a PLY (trailing blanks and any line end:
    LF, CRLF or CR), searched in its first MiB."""
    return re.search(rb"end_header[ \t]*(\r\n|\n|\r)", data[:1 << 20])


def _plain_ply_header(data: bytes) -> bytes:
    """The PLY with trailing white space cut from its header lines (``ply ``,
    ``end_header ``) and bytes beyond ASCII in its comment and obj_info lines
    replaced by ``?`` (a comment naming an author as UTF-8): MeshLab and
    trimesh read such headers, and plyfile had refused them ("the header is
    not ASCII text", "expected one of {}"). Line ends (LF, CRLF, CR) are
    kept; other files are returned unchanged."""
    m = _ply_header_end(data)
    if m is None or not data.startswith(b"ply"):
        return data
    head = data[:m.end()]
    if head.isascii() and not re.search(rb"[ \t]+(\r\n|\n|\r)", head):
        return data
    parts = re.split(rb"(\r\n|\n|\r)", head)  # lines and their ends, alternating, then b""
    for k in range(0, len(parts), 2):
        line = parts[k].rstrip(b" \t")
        if line.startswith((b"comment", b"obj_info")):
            line = bytes(c if c < 128 else 63 for c in line)
        parts[k] = line
    return b"".join(parts) + data[m.end():]


def _ascii_ply_body_start(data: bytes) -> int:
    """Offset of an ASCII PLY's body (after ``end_header`` and its line end),
    or 0 when the file is not an ASCII PLY (its ``format`` line says so, not a
    comment that mentions it)."""
    m = _ply_header_end(data)
    if m is None or not re.search(rb"^format[ \t]+ascii\b", data[:m.start()], flags=re.M):
        return 0
    return m.end()


def _without_blank_ascii_rows(data: bytes) -> bytes:
    """An ASCII PLY without the blank lines among its rows, which hold no row
    (MeshLab and trimesh read such files; plyfile took a blank line between
    the vertices and the faces for an empty face row). Other files are
    returned unchanged (the same object). Called only when the file did not
    read as it is: the search costs about a second per 70 MB."""
    start = _ascii_ply_body_start(data)
    if not start:
        return data
    body = data[start:].rstrip()
    if not re.search(rb"(\A|\n)[ \t\r\f\v]*(\n|\Z)", body):
        return data
    return data[:start] + b"\n".join(line for line in body.split(b"\n") if line.strip()) + b"\n"


def _nonblank_lines_after(data: bytes, offset: int, rows: int) -> int:
    """Number of lines holding anything but white space after byte ``offset``
    (the header's end), beyond ``rows``: the lines after the declared rows.
    Blank lines are not rows wherever they stand (plyfile skips them; counted
    as rows, one between the vertices and the faces had been reported as
    data after the rows)."""
    return max(0, len(re.findall(rb"^[ \t\r\f\v]*[^\s]", data[offset:], flags=re.M)) - rows)


def _require_declared_rows_fit(data: bytes, path: str):
    """InputError when the header's row counts cannot fit the bytes after it;
    else the header (:func:`geoproc.mesh.ply_uniform.parse_ply_header`, None
    for one it does not read), for the checks after plyfile.

    Each binary row takes at least its scalars and its list's count; each ASCII
    row at least one line. plyfile allocates every element before reading it,
    so a corrupt count would otherwise end in a failed allocation of many GiB.
    Headers :func:`geoproc.mesh.ply_uniform.parse_ply_header` does not read are
    left to plyfile.
    """
    long_count = re.search(rb"^element +(\S+) +0*[1-9][0-9]{%d,} *$" % MAX_COUNT_DIGITS,
                           data[:max(data.find(b"end_header"), 0)], re.M)
    if long_count:  # plyfile's int() would refuse past 4300 digits, with advice on Python's settings
        raise InputError(path, f"PLY header declares a count of more than {MAX_COUNT_DIGITS} digits for its "
                               f"'{_text(long_count.group(1))}' rows")
    header = parse_ply_header(data)
    if header is None:
        return None
    fmt, elements, offset = header
    body = len(data) - offset
    if fmt == "ascii":
        need = sum(e.count for e in elements)
        have = data.count(b"\n", offset) + (not data.endswith(b"\n"))
        if need > have:
            raise InputError(path, f"PLY header declares {_row_counts(elements)}, but only {have} "
                                   f"line{'s' * (have != 1)} follow{'s' * (have == 1)} it (one per row)")
        return header
    need = sum(e.count * smallest_row_bytes(e) for e in elements)
    if need > body:
        raise InputError(path, f"PLY header declares {_row_counts(elements)} (at least {need} bytes), "
                               f"but only {body} byte{'s' * (body != 1)} follow{'s' * (body == 1)} it")
    return header


def _first_element_has_a_short_row(data: bytes, header) -> bool:
    """Whether an ASCII PLY's first element (scalar properties only) has a declared
    row with fewer values than properties: a row written over two lines. A header
    that undercounts its rows leaves whole rows over; plyfile then fails on the
    next element, as it does on a row that ends early. ``header``: the file's
    :func:`geoproc.mesh.ply_uniform.parse_ply_header`."""
    if header is None or header[0] != "ascii" or not header[1] or header[1][0].list_types is not None:
        return False
    first = header[1][0]
    rows = data[header[2]:].split(b"\n", first.count)[: first.count]
    return any(len(row.split()) < len(first.scalars) for row in rows)


def _refuse_text_after_ascii_rows(data: bytes, path: str, header) -> None:
    """InputError when an ASCII PLY has text after its declared rows (plyfile
    stops at the last row and would drop it without a word); blank lines there
    are harmless. Called once plyfile has read the rows, so that a row written
    over two lines gets plyfile's message (its row and property), not this one.
    ``header``: the file's :func:`geoproc.mesh.ply_uniform.parse_ply_header`."""
    if header is None or header[0] != "ascii":
        return
    _, elements, offset = header
    need = sum(e.count for e in elements)
    have = data.count(b"\n", offset) + (not data.endswith(b"\n"))
    extra = _nonblank_lines_after(data, offset, need) if have > need else 0
    if extra:
        raise InputError(path, f"PLY header declares {_row_counts(elements)}, but {need + extra} "
                               "non-empty lines follow it (one per row): data after the declared rows")


def _row_counts(elements: list) -> str:
    """``'3 vertex rows and 1 face row'``: the header's counts for a message."""
    parts = [f"{e.count} {e.name} row{'s' * (e.count != 1)}" for e in elements]  # header or plyfile elements
    return " and ".join(parts) if len(parts) < 3 else ", ".join(parts[:-1]) + " and " + parts[-1]


def _plyfile_elements(data: bytes, path: str) -> dict[str, np.ndarray]:
    """Every element of a PLY file read by plyfile (lists as object arrays),
    keyed by name as ``PlyData[name]`` finds them; InputError when plyfile
    cannot parse the file."""
    from plyfile import PlyData

    # a list's count is its length: plyfile read an ASCII count of 3.99 under a float
    # count type as 3 (the vectorized reader leaves such headers to this one)
    # its own line (not a comment's words), after LF, CR LF or CR alone
    end = re.search(rb"(?:^|(?<=\r))end_header[ \t]*(\r\n|\n|\r)", data, re.M)
    head = data[:end.start()].replace(b"\r\n", b"\n").replace(b"\r", b"\n") if end else b""
    counted = re.search(rb"^property\s+list\s+(float|double|float32|float64)\s+\S+\s+(\S+)", head, re.M)
    if counted:
        raise InputError(path, f"PLY list property '{counted.group(2).decode('ascii', 'replace')}' has a count "
                               f"of type {counted.group(1).decode()}: a list's count is its length, of an "
                               "integer type (uchar, ushort, uint, int)")
    if end and re.search(rb"^format\s+ascii\b", head, re.M) and b"_" in data[end.end():]:
        # Python's number parsing, which plyfile's is, reads 1_0 as 10; OBJ and OFF refuse it too
        raise InputError(path, "unparseable PLY: '_' inside a number")
    stream = _NonNegativeReads(data)
    try:
        with warnings.catch_warnings():  # plyfile warns (multi-line) about empty list rows
            warnings.simplefilter("ignore")
            ply = PlyData.read(stream)
    except UnicodeDecodeError:
        raise InputError(path, "unparseable PLY: the header is not ASCII text") from None
    except Exception as exc:  # plyfile raises several types for malformed data
        if stream.negative_read:
            raise InputError(path, "unparseable PLY: a binary list row has a negative count") from None
        raise InputError(path, f"unparseable PLY: {first_line(exc)}") from exc
    if not ply.text:  # plyfile stops at the last declared row: more rows would be dropped without a word
        rest = data[stream.tell():]
        if rest.strip(b" \t\r\n\x0b\x0c\x00"):  # white space or zero padding is no row
            counts = _row_counts(ply.elements)
            raise InputError(path, f"PLY header declares {counts}, but {len(rest)} more "
                                   f"byte{'s' * (len(rest) != 1)} follow them: data after the declared rows")
    return {e.name: e.data for e in ply.elements}


class _NonNegativeReads(io.BytesIO):
    """The bytes of a PLY file for plyfile, refusing reads of a negative size.

    plyfile reads a binary list row's items as ``stream.read(count * size)``;
    a negative count there reads the rest of the file, so a last row with a
    count of -100 became one polygon of whatever bytes followed it."""

    negative_read = False

    def read(self, size: int | None = -1) -> bytes:
        if size is not None and size < 0:
            self.negative_read = True
            raise ValueError("a read of negative size")
        return super().read(size)


def _index_lists(rows: np.ndarray, key: str, path: str, element: str = "face") -> tuple[np.ndarray, np.ndarray]:
    """The index lists of property ``key`` stored back to back, and their lengths:
    from a (count, k) sub-array (:func:`geoproc.mesh.ply_uniform.read_uniform_ply`)
    or plyfile's object array of lists; InputError when ``key`` is no list."""
    values = rows[key]
    if values.ndim == 2:
        return values.reshape(-1), np.full(len(values), values.shape[1], dtype=np.int64)
    _require_list_property(rows, key, element, path)
    lists = list(values)
    counts = np.fromiter((len(f) for f in lists), dtype=np.int64, count=len(lists))
    flat = np.concatenate([np.asarray(f) for f in lists]) if lists else np.zeros(0, np.int64)
    return flat, counts


def _require_list_property(data: np.ndarray, key: str, element: str, path: str) -> None:
    """InputError unless the PLY property ``key`` of ``element`` is a list (plyfile
    stores lists as objects; a scalar property holds one index per row)."""
    if data.dtype[key].kind != "O":
        raise InputError(path, f"PLY {element} property '{key}' is a single {data.dtype[key]} per {element}, "
                               "not a list of vertex indices")


def _strip_triangles(raw: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """(m, 3) int64 triangles of PLY triangle strips (their vertex indices
    ``raw`` back to back, ``counts`` long each; -1 restarts a strip):
    ``(s_i, s_i+1, s_i+2)``, every other one reversed to keep the strip's
    orientation; triangles that repeat a vertex (the stitches between strips)
    are skipped. Vectorized over all strips."""
    # -1 restarts a strip; stored unsigned it reads as the type's largest value
    restart = (raw == -1) | ((raw == np.iinfo(raw.dtype).max) if raw.dtype.kind == "u" else False)
    ends = np.cumsum(counts)
    flat = np.insert(np.where(restart, -1, raw.astype(np.int64)), ends, -1)  # strips never join
    if len(flat) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    cut = flat == -1
    last_cut = np.maximum.accumulate(np.where(cut, np.arange(len(flat)), -1))
    i = np.arange(len(flat) - 2)
    a, b, c = flat[i], flat[i + 1], flat[i + 2]
    keep = ~(cut[i] | cut[i + 1] | cut[i + 2]) & (a != b) & (b != c) & (a != c)
    odd = (i - last_cut[i] - 1) % 2 == 1  # position in the strip
    tris = np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)
    return tris[keep]


def _require_integer_indices(flat: np.ndarray, counts: np.ndarray, path: str, what: str = "face") -> None:
    """Raise InputError when PLY index lists stored as floats (``flat``, the
    lists back to back, ``counts`` long each) hold a vertex index that is not
    an integer (1.5, inf, nan) or beyond 64-bit integers (1e30); ``what``
    names the list's element in the message."""
    if flat.dtype.kind != "f":
        return
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(flat) | (flat != np.round(flat)) | (np.abs(flat) >= 2.0**62)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        face = int(np.searchsorted(np.cumsum(counts), first, side="right"))
        kind = "a non-integer" if not np.isfinite(flat[first]) or flat[first] != np.round(flat[first]) \
            else "an out-of-range"
        raise InputError(path, f"{what} {face} has {kind} vertex index {flat[first]:g}")


_BLANKS = bytes.maketrans(b"\t\v\f", b"   ")  # tab, vertical tab, form feed: blanks as space


def _parse_obj(data: bytes, path: str) -> tuple[Mesh, int, list[str]]:
    """Parse the positions (``v``) and faces (``f``) of an OBJ file.

    Texture and normal references of face corners are ignored, so a mesh with
    UV seams keeps one vertex per stored position, in file order; negative
    indices count back from the face line (``-1``: the last vertex above it);
    extra values on a ``v`` line (a weight, a colour) are ignored; other
    statements (``vt``, ``vn``, ``l``, ``g``, ``usemtl``...) are skipped.
    Polygons are split into fans.

    Returns the mesh, the number of faces with more than three corners and
    what is not read (:func:`_obj_unread`).
    """
    if b"\r" in data:  # lines ending in CR LF or in CR alone: as LF, for the line-anchored patterns below
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if b"#" in data:
        data = re.sub(rb"#[^\r\n]*", b"", data)  # comments, also at the end of a v or f line
    if b"\\" in data:
        data = re.sub(rb"\\[ \t]*\r?\n", b" ", data)  # a trailing backslash continues the line
    if b"_" in data and re.search(rb"^[ \t]*[vf][ \t][^\r\n]*_", data, flags=re.M):
        raise InputError(path, "unparseable OBJ: '_' inside a number (a v or f line)")
    vlines, flines, seen = [], [], []
    for line in data.translate(_BLANKS).splitlines():
        head = line.lstrip()[:2]
        if head == b"v " or line.strip() == b"v":
            vlines.append(line.lstrip()[1:])
        elif head == b"f " or line.strip() == b"f":
            flines.append(line.lstrip()[1:])
            seen.append(len(vlines))
    V, width = _obj_vertices(vlines, path)
    if not flines:
        if len(V):
            raise InputError(path, "mesh has no faces (vertices only; store a point cloud as PLY)")
        raise InputError(path, "unparseable OBJ: no vertex or face lines")
    text = b"\n".join(flines)
    if b"/" in text:
        text = re.sub(rb"/[^\s]*", b"", text)
        flines = text.split(b"\n")
    got = numbers_on_lines(flines, integer=True)
    if got is not None:
        idx, counts = got
    else:  # a corner spelled otherwise: line by line, for the error
        counts = np.fromiter((len(ln.split()) for ln in flines), dtype=np.int64, count=len(flines))
    short = np.flatnonzero(counts < 3)
    if len(short):
        raise InputError(path, f"face {int(short[0])} has fewer than 3 corners")
    if got is None:
        try:
            idx = np.array(text.split(), dtype=np.int64)
        except ValueError:
            raise InputError(path, "unparseable OBJ: a face corner is not an integer vertex index") from None
        except OverflowError:
            raise InputError(path, "face index out of range (beyond 64-bit integers)") from None
    line_of = np.repeat(np.arange(len(flines)), counts)
    relative = idx < 0
    idx = np.where(relative, np.asarray(seen)[line_of] + idx, idx - 1)
    bad = np.flatnonzero((idx < 0) | (idx >= len(V)))
    if len(bad):
        k = int(bad[0])
        given = idx[k] - np.asarray(seen)[line_of[k]] if relative[k] else idx[k] + 1
        raise InputError(path, f"face index out of range: face {int(line_of[k])} references vertex {int(given)}, "
                               f"but the file has {len(V)} vertices (1-based)")
    if (counts == 3).all():
        return Mesh(V, idx.reshape(-1, 3)), 0, _obj_unread(data, width)
    F, polygons = _fans(idx, counts)
    return Mesh(V, F), polygons, _obj_unread(data, width)


_OBJ_UNREAD = (
    (rb"^[ \t]*vt[ \t]", "texture coordinates (vt)"),
    (rb"^[ \t]*vn[ \t]", "vertex normals (vn)"),
    (rb"^[ \t]*(usemtl|mtllib)[ \t]", "materials (usemtl, mtllib)"),
    (rb"^[ \t]*[lp][ \t]", "polylines or points (l, p)"),
)


def _obj_unread(data: bytes, width: int) -> list[str]:
    """What an OBJ (comments removed, lines ending in LF) stores that is not read: texture
    coordinates, normals, materials, polylines and points, and colours
    after a vertex's position (``width``, the most numbers on a ``v`` line,
    is 6 or more; a fourth number alone is the weight w)
    (see :attr:`geoproc.mesh.mesh.LoadLog.unread_properties`)."""
    unread = [what for pattern, what in _OBJ_UNREAD[:2] if re.search(pattern, data, flags=re.M)]
    unread += ["colours after x y z on v lines"] if width >= 6 else []
    return unread + [what for pattern, what in _OBJ_UNREAD[2:] if re.search(pattern, data, flags=re.M)]


def _obj_vertices(lines: list, path: str) -> tuple[np.ndarray, int]:
    """(n, 3) float64: the first three numbers of each OBJ ``v`` line (after
    the ``v``), and the most numbers on a line."""
    X, _, width = _leading_numbers(lines, 3, path,  # numbered from 1, as OBJ faces count them
                                   lambda i, line: f"OBJ vertex {i + 1} (1-based): 'v {line}' does not hold "
                                                   "three numbers")
    return X, width


def _leading_numbers(lines: list, k: int, path: str, problem) -> tuple[np.ndarray, int, int]:
    """(n, k) float64: the first k numbers of each line (bytes), extra values
    ignored, and the fewest and the most values on a line (0 for no line);
    one vectorized parse when every line has the same count.

    ``problem(i, text)`` words the InputError for line i that does not start
    with k numbers.
    """
    rows = uniform_rows(lines, integer=False)
    if rows is not None and rows.shape[1] >= k:  # the common case
        return rows[:, :k].copy(), rows.shape[1], rows.shape[1]
    X = np.empty((len(lines), k), dtype=np.float64)
    narrow, width = (1 << 62 if lines else 0), 0
    for i, line in enumerate(lines):
        try:
            tokens = line.split()
            narrow, width = min(narrow, len(tokens)), max(width, len(tokens))
            if len(tokens) < k:
                raise ValueError
            X[i] = [float(t) for t in tokens[:k]]
        except ValueError:
            raise InputError(path, problem(i, _text(line).strip())) from None
    return X, narrow, width


def _parse_with_trimesh(data: bytes, fmt: str, path: str) -> tuple[Mesh, int]:
    """STL, through trimesh."""
    import trimesh

    log = logging.getLogger("trimesh")  # it logs a traceback for a malformed stored normal, which is not used
    level = log.level
    log.setLevel(logging.CRITICAL + 1)
    try:
        # trimesh computes face normals as it loads: an infinite corner makes numpy warn,
        # and the finite check after loading names the vertex in one line
        with np.errstate(invalid="ignore", over="ignore"):
            loaded = trimesh.load(io.BytesIO(data), file_type=fmt, process=False, force="mesh")
    except IndexError as exc:
        raise InputError(path, f"face index out of range ({first_line(exc)})") from exc
    except Exception as exc:  # trimesh raises many types for malformed files
        msg = first_line(exc)
        if "index" in msg.lower() and "range" in msg.lower():
            raise InputError(path, f"face index out of range ({msg})") from exc
        raise InputError(path, f"unparseable {fmt.upper()}: {_stl_problem(data) or msg}") from exc
    finally:
        log.setLevel(level)
    V = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    F = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    uneven = _ascii_stl_uneven_facet(data) if fmt == "stl" else None
    if uneven is not None:  # trimesh reads the corners in threes whatever the facets hold
        raise InputError(path, f"unparseable STL: ASCII facet {uneven[0]} lists {uneven[1]} vertices; each facet has 3")
    if V.size == 0 and fmt == "stl" and _stl_without_facets(data):
        raise InputError(path, "mesh has no vertices (an STL of no facets)")
    if V.size == 0 and len(data.strip()) > 0:
        raise InputError(path, f"unparseable {fmt.upper()}: {_stl_problem(data) or 'no vertices could be read'}")
    if len(V) != 3 * len(F) and len(F) and F.min() >= 0 and F.max() < len(V):
        # an ASCII STL of several solids comes back with each solid's corners merged:
        # give the file's corners as stored, three per facet, as for a single solid
        V, F = V[F].reshape(-1, 3), np.arange(3 * len(F), dtype=np.int64).reshape(-1, 3)
    return Mesh(V, F), 0


# an OFF keyword: [ST][C][N][4][n]OFF (texture, colour, normals, homogeneous, dimension);
# MeshLab writes NCOFF for a mesh with normals and colours, so N may come before C
_OFF_KEYWORD = re.compile(rb"(?P<st>ST)?(?P<cn>C|N|CN|NC)?(?P<w>4)?(?P<n>n)?OFF")


def _parse_off(data: bytes, path: str) -> tuple[Mesh, int, list[str]]:
    """Parse an ASCII OFF file: any keyword ``[ST][C][N][4][n]OFF`` or MeshLab's ``NCOFF`` (texture
    coordinates, normals and colours after the position are ignored; 4OFF
    positions are divided by w; nOFF must be 3-D), or none (a first line of
    counts); polygons are split into fans.

    Files with one vertex or face per line are read a block of lines at a
    time. The format itself only asks for the vertex values in order, and
    for each face's colour to end its line: a file whose values wrap over
    lines otherwise (and that has no per-vertex colours, whose count a line
    end would tell) is read as such a stream (:func:`_off_free_form`).

    Returns the mesh, the number of faces with more than three corners and
    what is not read (:func:`_off_unread`).
    Raises InputError for binary OFF, a file shorter than its header says, a
    short face line or a coordinate that is not a number.
    """
    text = re.sub(rb"#[^\r\n]*", b"", data) if b"#" in data else data
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise InputError(path, "unparseable OFF: no header (only comments or blank lines)")
    if b"_" in text:
        raise InputError(path, "unparseable OFF: '_' inside a number")
    head = lines[0].split()
    kind = _OFF_KEYWORD.fullmatch(head[0])
    if kind is None and head[0].lower() == b"off":
        kind = _OFF_KEYWORD.fullmatch(b"OFF")
    if kind is None:  # the keyword is optional: a first line of counts
        if not all(t.isdigit() for t in head) or len(head) not in (2, 3):
            raise InputError(path, f"unparseable OFF: the first line '{_text(lines[0]).strip()[:40]}' "
                                   "is neither an OFF keyword nor the vertex and face counts")
        counts, start, homogeneous = head, 1, False
    else:
        rest, start, homogeneous = head[1:], 1, kind.group("w") is not None
        if any(t.upper() == b"BINARY" for t in rest):
            raise InputError(path, "binary OFF is not supported (write it as ASCII OFF, PLY, OBJ or STL)")
        if kind.group("n") is not None:  # nOFF: the dimension comes first
            if not rest and len(lines) > 1:
                rest, start = lines[1].split(), 2
            dim = rest[0] if rest else b"?"
            if dim != b"3":
                raise InputError(path, f"nOFF of dimension {_text(dim)}: only 3-D vertices are read")
            rest = rest[1:]
        counts = rest
        if not counts and len(lines) > start:
            counts, start = lines[start].split(), start + 1
    try:
        nv, nf = int(counts[0]), int(counts[1])
    except (IndexError, ValueError):
        raise InputError(path, "OFF header lacks the vertex and face counts") from None
    if nv < 0 or nf < 0:
        raise InputError(path, f"OFF header declares {nv} vertices and {nf} face{'s' * (nf != 1)}: "
                               "counts cannot be negative")
    unread = _off_keyword_unread(kind)
    cn = (kind.group("cn") or b"") if kind is not None else b""
    per_vertex = 3 + homogeneous  # x y z [w], then the normal and texture coordinates the keyword names
    if kind is not None:
        per_vertex += 3 * (b"N" in cn) + 2 * (kind.group("st") is not None)
    try:
        mesh, polygons, width, face_colours = _off_by_lines(lines[start:], nv, nf, path, homogeneous, per_vertex)
        if width > per_vertex + 4 * (b"C" in cn):  # a colour is 3 or 4 values
            unread.append("values on vertex lines beyond those the keyword names (colours)")
        return mesh, polygons, unread + ["face colours"] * face_colours
    except InputError:
        if kind is not None and b"C" in (kind.group("cn") or b""):  # colours: their count ends with the line
            raise
        lead = [b" ".join(counts[3:])] if len(counts) > 3 else []  # values after NVERTICES NFACES NEDGES
        free = _off_free_form(lead + lines[start:], nv, nf, per_vertex, homogeneous)
        if free is None:
            raise
        V, faces, face_colours = free
    F, polygons = _fan_triangulate(faces) if faces else (np.zeros((0, 3), dtype=np.int64), 0)
    return Mesh(V, F), polygons, unread + ["face colours"] * face_colours


def _off_keyword_unread(kind: re.Match | None) -> list[str]:
    """What an OFF's keyword says it stores and is not read: texture
    coordinates ``ST``, normals ``N``, colours ``C``."""
    cn = (kind.group("cn") or b"") if kind is not None else b""
    unread = ["vertex texture coordinates (ST)"] if kind is not None and kind.group("st") else []
    unread += ["vertex normals (N)"] if b"N" in cn else []
    return unread + (["vertex colours (C)"] if b"C" in cn else [])


def _off_by_lines(lines: list, nv: int, nf: int, path: str, homogeneous: bool,
                  per_vertex: int = 3) -> tuple[Mesh, int, int, bool]:
    """The vertices and faces of an OFF file after its header, one per line
    (``lines`` without blank ones); see :func:`_parse_off`. Returns the mesh,
    its polygon count, the most values on a vertex line and whether a face
    line holds values after its corners (a colour)."""
    have = len(lines)
    if have < nv + nf:
        raise InputError(path, f"OFF header declares {nv} vertices and {nf} face{'s' * (nf != 1)}, "
                         f"but only {max(have, 0)} lines follow it (one per vertex, then one per face)")
    if have > nv + nf:
        raise InputError(path, f"OFF header declares {nv} vertices and {nf} face{'s' * (nf != 1)}, "
                         f"but {have} non-empty lines follow it (one per vertex, then one per face): "
                         "data after the declared faces")
    V, width = _off_vertices(lines[:nv], path, homogeneous, per_vertex)
    face_lines = lines[nv: nv + nf]
    T = uniform_rows(face_lines, integer=True)
    if T is not None and T.shape[1] >= 4 and (T[:, 0] == 3).all():  # every line '3 a b c' (and a colour)
        return Mesh(V, T[:, 1:4].copy()), 0, width, T.shape[1] > 4
    faces = []
    coloured = False
    for i, line in enumerate(face_lines):
        tokens = line.split()
        try:
            corners = int(tokens[0])
        except ValueError:
            raise InputError(path, f"OFF face {i}: '{_text(tokens[0])}' is not a corner count") from None
        if len(tokens) - 1 < corners:
            raise InputError(path, f"OFF face {i} declares {corners} corners but lists {len(tokens) - 1}")
        if corners < 3:
            raise InputError(path, f"face {i} has fewer than 3 corners")
        try:
            face = [int(t) for t in tokens[1: 1 + corners]]
        except ValueError:
            raise InputError(path, f"OFF face {i}: the corners are not all integers") from None
        if max(map(abs, face)) >= 2**62:
            raise InputError(path, f"face index out of range: OFF face {i} references vertex {max(face, key=abs)}")
        faces.append(face)
        coloured |= len(tokens) > 1 + corners
    F, polygons = _fan_triangulate(faces) if faces else (np.zeros((0, 3), dtype=np.int64), 0)
    return Mesh(V, F), polygons, width, coloured


def _off_free_form(lines: list, nv: int, nf: int, per_vertex: int,
                   homogeneous: bool) -> tuple[np.ndarray, list] | None:
    """An OFF body read as the format defines it: ``per_vertex`` values for
    each of the ``nv`` vertices in order, whatever the line breaks; then per
    face its corner count and corners, the rest of the line where the
    corners end being its colour. ``lines`` follow the header (no blank
    ones). Returns ``((nv, 3) positions, faces as lists of corners)``, or
    None when the body does not read so (too few values, a value that is
    not a number, a face of fewer than three corners, w = 0 in 4OFF): the
    caller then reports what the line-by-line reading found.
    """
    need = nv * per_vertex
    values: list = []
    row = 0
    rest: list = []
    while len(values) < need and row < len(lines):
        tokens = lines[row].split()
        want = need - len(values)
        values += tokens[:want]
        rest = tokens[want:]
        row += 1
    if len(values) < need:
        return None
    try:
        X = np.array([float(t) for t in values], dtype=np.float64).reshape(nv, per_vertex)
    except ValueError:
        return None
    if homogeneous:
        if (X[:, 3] == 0).any():
            return None
        with np.errstate(over="ignore", invalid="ignore"):  # a w of 1e-320 overflows: the finite check names it
            X = X[:, :3] / X[:, 3:4]
    cur, pos, nxt = rest, 0, row  # the values of the line being read, the next one to read, the next line

    def take(k: int) -> list | None:
        """The next k values as integers, across lines; None if the body ends first or one is not an integer."""
        nonlocal cur, pos, nxt
        out: list = []
        while len(out) < k:
            if pos == len(cur):
                if nxt == len(lines):
                    return None
                cur, pos, nxt = lines[nxt].split(), 0, nxt + 1
                continue
            n = min(k - len(out), len(cur) - pos)
            out += cur[pos: pos + n]
            pos += n
        try:
            ints = [int(t) for t in out]
        except ValueError:
            return None
        return ints if all(abs(i) < 2**62 for i in ints) else None

    faces = []
    coloured = False
    for _ in range(nf):
        count = take(1)
        if count is None or count[0] < 3:
            return None
        face = take(count[0])
        if face is None:
            return None
        faces.append(face)
        coloured |= pos < len(cur)
        pos = len(cur)  # the rest of the line is the face's colour
    if nxt < len(lines):
        return None  # lines after the declared faces
    return X[:, :3].copy(), faces, coloured


def _off_vertices(lines: list, path: str, homogeneous: bool = False,
                  per_vertex: int = 3) -> tuple[np.ndarray, int]:
    """(n, 3) float64: the first three numbers of each OFF vertex line, or
    with ``homogeneous`` (4OFF) the first four, x y z divided by w; and the
    most values on a line. InputError for a line of fewer than ``per_vertex``
    values (what the keyword names: the caller then reads the values as a
    stream wrapped over lines)."""
    words = "four" if homogeneous else "three"
    X, narrow, width = _leading_numbers(lines, 4 if homogeneous else 3, path,
                                        lambda i, line: f"OFF vertex {i}: '{line}' does not start with {words} numbers")
    if lines and narrow < per_vertex:
        raise InputError(path, f"an OFF vertex line holds {narrow} values, fewer than the {per_vertex} "
                               "its keyword names")
    if not homogeneous:
        return X, width
    zero = np.flatnonzero(X[:, 3] == 0)
    if len(zero):
        raise InputError(path, f"4OFF vertex {int(zero[0])} has w = 0 (a point at infinity)")
    with np.errstate(over="ignore", invalid="ignore"):  # a w of 1e-320 overflows: the finite check names it
        return X[:, :3] / X[:, 3:], width


def _binary_stl_triangles(data: bytes) -> int | None:
    """The triangle count a binary STL declares in bytes 80-84, when the length
    of ``data`` is exactly what that count needs (84 + 50 per triangle), else None."""
    if len(data) < 84:
        return None
    count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
    return count if len(data) == 84 + 50 * count else None


def _stl_problem(data: bytes) -> str | None:
    """What is wrong with an STL that trimesh could not read, when its layout
    tells: an ASCII one (``solid`` first, no NUL byte) without ``endsolid`` or
    with a facet of other than three vertices, a binary one whose length is not
    84 bytes plus 50 per facet it declares. None when neither tells."""
    text = data.lstrip()
    if text[:5].lower() == b"solid" and b"\0" not in data[:4096]:
        low = text.lower()
        if b"endsolid" not in low:
            return "an ASCII STL without 'endsolid' (cut short?)"
        facets = len(re.findall(rb"^\s*facet\b", low, re.M))
        corners = len(re.findall(rb"^\s*vertex\b", low, re.M))
        if corners != 3 * facets:
            return f"an ASCII STL of {facets} facet{'s' * (facets != 1)} lists {corners} vertices; each facet has 3"
        return None
    if len(data) < 84:
        return f"a binary STL has an 84-byte header, but the file has only {len(data)} bytes"
    count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
    need = 84 + 50 * count
    if len(data) != need:
        return (f"a binary STL that declares {count} facet{'s' * (count != 1)} takes {need} bytes, "
                f"but the file has {len(data)}")
    return None


def _ascii_stl_uneven_facet(data: bytes) -> tuple[int, int] | None:
    """For an ASCII STL (``solid`` first, no NUL byte), the first facet that
    does not list three vertices and how many it lists; None when every one
    does, or the file is binary."""
    text = data.lstrip()
    if text[:5].lower() != b"solid" or b"\0" in data[:4096]:
        return None
    # the words as trimesh reads them (separated by white space, anywhere on a line: 'outer loop
    # vertex 0 0 0' is a corner), leaving out the solids' names
    low = text.lower()
    first = re.search(rb"[\r\n]", low)  # the header line, whatever it names (trimesh skips it)
    body = re.sub(rb"endsolid[^\r\n]*|^[ \t]*solid[^\r\n]*", b"", low[first.end():] if first else b"", flags=re.M)
    words = np.array(re.findall(rb"\s(facet|vertex)(?=\s)", body))
    if not len(words):
        return None
    facet = np.cumsum(words == b"facet") - 1
    corner = (words == b"vertex") & (facet >= 0)
    counts = np.bincount(facet[corner], minlength=int(facet[-1]) + 1)
    bad = np.flatnonzero(counts != 3)
    return (int(bad[0]), int(counts[bad[0]])) if len(bad) else None


def _stl_without_facets(data: bytes) -> bool:
    """Whether ``data`` is a well-formed STL that holds no facet: a binary one of
    84 bytes declaring 0 triangles, or an ASCII ``solid`` with no ``facet``."""
    if _binary_stl_triangles(data) == 0:
        return True
    text = data.lstrip().lower()
    return text.startswith(b"solid") and b"facet" not in text and b"endsolid" in text
