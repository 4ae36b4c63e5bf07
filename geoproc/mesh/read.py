"""Read OBJ, PLY (ASCII and binary), OFF and STL files into a :class:`Mesh`.

PLY goes through plyfile so that every named vertex and face property comes back
exactly (positions and fields as float64); OBJ and ASCII OFF (also COFF, NOFF,
STOFF) are parsed here, vectorized; STL and the other OFF variants go through
trimesh with ``process=False``. Polygons with more than three corners are triangulated as fans
and counted in ``mesh.log.triangulated_polygons``. After reading, the mesh is
validated (see :func:`validate_arrays`) and, unless ``clean=False``, cleaned by
:func:`geoproc.mesh.clean.clean_mesh`.
"""

from __future__ import annotations

import io
import os
import re
import warnings

import numpy as np

from geoproc.errors import InputError
from geoproc.fileio import file_extension, read_input_bytes, require_input_file
from geoproc.mesh.clean import clean_mesh
from geoproc.mesh.mesh import LoadLog, Mesh

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


def sniff_format(data: bytes, path: str = "-") -> str:
    """Guess the mesh format of raw bytes (for standard input)."""
    head = re.sub(rb"^(\s*#[^\n]*\n)+", b"", data[:4096]).lstrip()  # OFF and OBJ allow leading comments
    if head.startswith(b"ply"):
        return "ply"
    if head[:3] in (b"OFF", b"COF", b"NOF") or head.startswith(b"STOFF"):
        return "off"
    if head.startswith(b"solid") and b"facet" in data[:4096]:
        return "stl"
    if len(data) >= 84:
        n = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        if len(data) == 84 + 50 * n:
            return "stl"
    if re.search(rb"^\s*(v|f)\s", data[:65536], flags=re.M):
        return "obj"
    raise InputError(path, "cannot tell the mesh format of the data (not PLY, OFF, STL or OBJ)")


def read_mesh_bytes(data: bytes, fmt: str, path: str = "-", clean: bool = True) -> Mesh:
    """Parse ``data`` in format ``fmt`` (see :func:`load_mesh`)."""
    if len(data) == 0:
        raise InputError(path, "file is empty")
    if data.startswith(b"\xef\xbb\xbf") and fmt in ("obj", "off"):  # a UTF-8 byte order mark
        data = data[3:]
    parsed = _parse_off(data, path) if fmt == "off" else None
    if fmt == "ply":
        mesh, polys = _parse_ply(data, path)
    elif fmt == "obj":
        mesh, polys = _parse_obj(data, path)
    elif parsed is not None:
        mesh, polys = parsed
    else:
        mesh, polys = _parse_with_trimesh(data, fmt, path)
    mesh.log = LoadLog(
        path=path,
        format=fmt,
        stored_vertices=len(mesh.V),
        stored_faces=len(mesh.F),
        triangulated_polygons=polys,
        cleaned=clean,
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
    extent = float(np.linalg.norm(P.max(axis=0) - P.min(axis=0))) if V.size else 0.0
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
        raise InputError(path, "mesh has no faces")
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise InputError(
            path, f"{int(bad.sum())} vertices have non-finite coordinates (first: vertex {first})"
        )
    require_coordinates_in_range(V, path)
    if len(F):
        out = (F < 0) | (F >= len(V))
        if out.any():
            f = int(np.flatnonzero(out.any(axis=1))[0])
            raise InputError(
                path,
                f"face index out of range: face {f} references vertex {int(F[f][out[f]][0])}, "
                f"but there are {len(V)} vertices (0-based)",
            )


def _fan_triangulate(faces: list) -> tuple[np.ndarray, int]:
    """Split polygons (lists of vertex indices) into triangle fans.

    Returns the (m, 3) triangles and the number of polygons with more than three
    corners. Faces with fewer than three corners are rejected by the caller.
    """
    lengths = np.fromiter((len(f) for f in faces), dtype=np.int64, count=len(faces))
    if len(faces) and (lengths == 3).all():
        return np.asarray(np.stack(faces), dtype=np.int64).reshape(-1, 3), 0
    tris = []
    for f in faces:
        f = np.asarray(f, dtype=np.int64)
        for k in range(1, len(f) - 1):
            tris.append((f[0], f[k], f[k + 1]))
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3), int((lengths > 3).sum())


def _parse_ply(data: bytes, path: str) -> tuple[Mesh, int]:
    from plyfile import PlyData

    try:
        with warnings.catch_warnings():  # plyfile warns (multi-line) about empty list rows
            warnings.simplefilter("ignore")
            ply = PlyData.read(io.BytesIO(data))
    except UnicodeDecodeError:
        raise InputError(path, "unparseable PLY: the header is not ASCII text") from None
    except Exception as exc:  # plyfile raises several types for malformed data
        raise InputError(path, f"unparseable PLY: {_one_line(exc)}") from exc
    names = [e.name for e in ply.elements]
    if "vertex" not in names:
        raise InputError(path, "PLY has no 'vertex' element")
    vert = ply["vertex"].data
    for axis in "xyz":
        if axis not in vert.dtype.names:
            raise InputError(path, f"PLY vertex element has no '{axis}' property")
        if vert.dtype[axis].kind not in "fiu" or vert.dtype[axis].shape != ():
            raise InputError(path, f"PLY vertex property '{axis}' is not a number (a list?)")
    V = np.column_stack([np.asarray(vert[a], dtype=np.float64) for a in "xyz"])
    vfields = {
        n: np.asarray(vert[n], dtype=np.float64)
        for n in vert.dtype.names
        if n not in ("x", "y", "z") and vert.dtype[n].shape == () and vert.dtype[n].kind in "fiub"
    }
    F = np.zeros((0, 3), dtype=np.int64)
    ffields: dict[str, np.ndarray] = {}
    polys = 0
    if "face" in names and len(ply["face"].data):
        fdata = ply["face"].data
        key = next((k for k in ("vertex_indices", "vertex_index") if k in fdata.dtype.names), None)
        if key is None:
            raise InputError(path, "PLY face element has no 'vertex_indices' list")
        faces = list(fdata[key])
        short = [i for i, f in enumerate(faces) if len(f) < 3]
        if short:
            raise InputError(path, f"face {short[0]} has fewer than 3 corners")
        _require_integer_indices(faces, path)
        F, polys = _fan_triangulate(faces)
        if polys == 0:
            ffields = {
                n: np.asarray(fdata[n], dtype=np.float64)
                for n in fdata.dtype.names
                if n != key and fdata.dtype[n].shape == () and fdata.dtype[n].kind in "fiub"
            }
    if "tristrips" in names and len(ply["tristrips"].data):
        sdata = ply["tristrips"].data
        if "vertex_indices" not in sdata.dtype.names:
            raise InputError(path, "PLY tristrips element has no 'vertex_indices' list")
        strips = list(sdata["vertex_indices"])
        _require_integer_indices(strips, path)
        F = np.concatenate([F, _strip_triangles(strips)])
        ffields = {}  # per-face properties belong to the face element alone
    return Mesh(V, F, vfields, ffields), polys


def _strip_triangles(strips: list) -> np.ndarray:
    """(m, 3) int64 triangles of PLY triangle strips (each a list of vertex
    indices, -1 restarting the strip): ``(s_i, s_i+1, s_i+2)``, every other one
    reversed to keep the strip's orientation; triangles that repeat a vertex
    (the stitches between strips) are skipped."""
    tris = []
    for strip in strips:
        runs = np.split(np.asarray(strip, dtype=np.int64), np.flatnonzero(np.asarray(strip) == -1))
        for run in runs:
            run = run[run != -1]
            for i in range(len(run) - 2):
                a, b, c = run[i], run[i + 1], run[i + 2]
                if a != b and b != c and a != c:
                    tris.append((a, b, c) if i % 2 == 0 else (b, a, c))
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def _require_integer_indices(faces: list, path: str) -> None:
    """Raise InputError when a PLY face list stored as floats holds a
    non-integer vertex index (such as 1.5)."""
    if not faces or np.asarray(faces[0]).dtype.kind != "f":
        return
    flat = np.concatenate(faces)
    bad = flat != np.round(flat)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        face = int(np.searchsorted(np.cumsum([len(f) for f in faces]), first, side="right"))
        raise InputError(path, f"face {face} has a non-integer vertex index {flat[first]:g}")


def _parse_obj(data: bytes, path: str) -> tuple[Mesh, int]:
    """Parse the positions (``v``) and faces (``f``) of an OBJ file.

    Texture and normal references of face corners are ignored, so a mesh with
    UV seams keeps one vertex per stored position, in file order; negative
    indices count back from the face line (``-1``: the last vertex above it);
    extra values on a ``v`` line (a weight, a colour) are ignored; other
    statements (``vt``, ``vn``, ``l``, ``g``, ``usemtl``...) are skipped.
    Polygons are split into fans.

    Returns the mesh and the number of faces with more than three corners.
    """
    if b"#" in data:
        data = re.sub(rb"#[^\r\n]*", b"", data)  # comments, also at the end of a v or f line
    vlines, flines, seen = [], [], []
    for line in data.replace(b"\t", b" ").splitlines():
        head = line.lstrip()[:2]
        if head == b"v ":
            vlines.append(line.lstrip()[2:])
        elif head == b"f " or line.strip() == b"f":
            flines.append(line.lstrip()[1:])
            seen.append(len(vlines))
    V = _obj_vertices(vlines, path)
    if not flines:
        if len(V):
            raise InputError(path, "mesh has no faces (vertices only; store a point cloud as PLY)")
        raise InputError(path, "unparseable OBJ: no vertex or face lines")
    text = b"\n".join(flines)
    if b"/" in text:
        text = re.sub(rb"/[^\s]*", b"", text)
        flines = text.split(b"\n")
    counts = np.fromiter((len(ln.split()) for ln in flines), dtype=np.int64, count=len(flines))
    short = np.flatnonzero(counts < 3)
    if len(short):
        raise InputError(path, f"face {int(short[0])} has fewer than 3 corners")
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
        return Mesh(V, idx.reshape(-1, 3)), 0
    faces = np.split(idx, np.cumsum(counts)[:-1])
    F, polygons = _fan_triangulate(faces)
    return Mesh(V, F), polygons


def _obj_vertices(lines: list, path: str) -> np.ndarray:
    """(n, 3) float64: the first three numbers of each OBJ ``v`` line (after the ``v``)."""
    if not lines:
        return np.zeros((0, 3), dtype=np.float64)
    try:  # the common case, three numbers per line: one vectorized parse
        flat = np.array(b" ".join(lines).split(), dtype=np.float64)
        if len(flat) == 3 * len(lines):
            return flat.reshape(-1, 3)
    except ValueError:
        pass
    V = np.empty((len(lines), 3), dtype=np.float64)
    for i, line in enumerate(lines):
        try:
            tokens = line.split()[:3]
            if len(tokens) < 3:
                raise ValueError
            V[i] = [float(t) for t in tokens]
        except ValueError:
            raise InputError(path, f"OBJ vertex {i}: 'v {line.decode('latin-1').strip()}' "
                             "does not hold three numbers") from None
    return V


def _parse_with_trimesh(data: bytes, fmt: str, path: str) -> tuple[Mesh, int]:
    """STL, and the OFF variants :func:`_parse_off` leaves to trimesh."""
    import trimesh

    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=fmt, process=False, force="mesh")
    except IndexError as exc:
        raise InputError(path, f"face index out of range ({_one_line(exc)})") from exc
    except Exception as exc:  # trimesh raises many types for malformed files
        msg = _one_line(exc)
        if "index" in msg.lower() and "range" in msg.lower():
            raise InputError(path, f"face index out of range ({msg})") from exc
        raise InputError(path, f"unparseable {fmt.upper()}: {msg}") from exc
    V = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    F = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    if V.size == 0 and len(data.strip()) > 0:
        raise InputError(path, f"unparseable {fmt.upper()}: no vertices could be read")
    return Mesh(V, F), 0


def _parse_off(data: bytes, path: str) -> tuple[Mesh, int] | None:
    """Parse an ASCII OFF file (also COFF, NOFF, STOFF: the extra per-vertex
    values and per-face colours are ignored); polygons are split into fans.

    Returns the mesh and the number of faces with more than three corners, or
    None for variants this parser leaves to trimesh (4OFF, nOFF, binary).
    Raises InputError for a file shorter than its header says, a short face
    line or a coordinate that is not a number.
    """
    text = re.sub(rb"#[^\r\n]*", b"", data) if b"#" in data else data
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        return None
    head = lines[0].split()
    kind = head[0]
    # 4OFF (homogeneous), nOFF (any dimension) and binary files go to trimesh
    if not kind.upper().endswith(b"OFF") or b"4" in kind or kind.startswith(b"n") \
            or any(t.upper() == b"BINARY" for t in head[1:]):
        return None
    counts, start = head[1:], 1
    if not counts and len(lines) > 1:
        counts, start = lines[1].split(), 2
    try:
        nv, nf = int(counts[0]), int(counts[1])
    except (IndexError, ValueError):
        raise InputError(path, "OFF header lacks the vertex and face counts") from None
    have = len(lines) - start
    if nv < 0 or nf < 0 or have < nv + nf:
        raise InputError(path, f"OFF header declares {nv} vertices and {nf} face{'s' * (nf != 1)}, "
                         f"but only {max(have, 0)} lines follow it (one per vertex, then one per face)")
    V = _off_vertices(lines[start: start + nv], path)
    face_lines = lines[start + nv: start + nv + nf]
    F = _off_triangles(face_lines)
    if F is not None:
        return Mesh(V, F), 0
    faces = []
    for i, line in enumerate(face_lines):
        tokens = line.split()
        try:
            corners = int(tokens[0])
        except ValueError:
            raise InputError(path, f"OFF face {i}: '{tokens[0].decode('latin-1')}' is not a corner count") from None
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
    F, polygons = _fan_triangulate(faces) if faces else (np.zeros((0, 3), dtype=np.int64), 0)
    return Mesh(V, F), polygons


def _off_vertices(lines: list, path: str) -> np.ndarray:
    """(n, 3) float64: the first three numbers of each OFF vertex line."""
    counts = {len(ln.split()) for ln in lines}
    if len(counts) == 1 and min(counts) >= 3:
        try:  # the common case, every line alike: one vectorized parse
            return np.array(b" ".join(lines).split(), dtype=np.float64).reshape(len(lines), -1)[:, :3].copy()
        except ValueError:
            pass
    V = np.empty((len(lines), 3), dtype=np.float64)
    for i, line in enumerate(lines):
        try:
            V[i] = [float(t) for t in line.split()[:3]]
        except ValueError:
            raise InputError(path, f"OFF vertex {i}: '{line.decode('latin-1').strip()}' "
                             "does not start with three numbers") from None
    return V


def _off_triangles(lines: list) -> np.ndarray | None:
    """(m, 3) int64 when every OFF face line is ``3 a b c`` (plus the same
    number of colour values); None otherwise (the caller checks line by line)."""
    if not lines or len({len(ln.split()) for ln in lines}) != 1:
        return None
    try:
        T = np.array(b" ".join(lines).split(), dtype=np.int64).reshape(len(lines), -1)
    except (ValueError, OverflowError):
        return None
    if T.shape[1] < 4 or not (T[:, 0] == 3).all():
        return None
    return T[:, 1:4].copy()


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
