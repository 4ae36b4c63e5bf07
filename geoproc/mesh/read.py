"""Read OBJ, PLY (ASCII and binary), OFF and STL files into a :class:`Mesh`.

PLY goes through plyfile so that every named vertex and face property comes back
exactly (positions and fields as float64); OBJ, OFF and STL go through trimesh with
``process=False``. Polygons with more than three corners are triangulated as fans
and counted in ``mesh.log.triangulated_polygons``. After reading, the mesh is
validated (see :func:`validate_arrays`) and, unless ``clean=False``, cleaned by
:func:`geoproc.mesh.clean.clean_mesh`.
"""

from __future__ import annotations

import io
import os
import re

import numpy as np

from geoproc.errors import InputError
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
        if stdin_bytes is None:
            raise InputError("-", "no data on standard input")
        data = stdin_bytes
        fmt = sniff_format(data, name)
    else:
        _require_readable_file(name)
        fmt = format_from_extension(name)
        data = _read_bytes(name)
    return read_mesh_bytes(data, fmt, name, clean=clean)


def format_from_extension(path: str) -> str:
    """The mesh format named by the file extension, or InputError."""
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    if ext not in MESH_FORMATS:
        shown = f"'.{ext}'" if ext else "no extension"
        raise InputError(path, f"unknown mesh format ({shown}); expected .obj, .ply, .off or .stl")
    return ext


def sniff_format(data: bytes, path: str = "-") -> str:
    """Guess the mesh format of raw bytes (for standard input)."""
    head = data[:512].lstrip()
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
    if fmt == "ply":
        mesh, polys = _parse_ply(data, path)
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


MAX_COORDINATE = 1e150  # squared distances of larger coordinates overflow float64


def require_coordinates_in_range(V: np.ndarray, path: str) -> None:
    """Raise InputError when a finite coordinate of V (any shape) exceeds
    :data:`MAX_COORDINATE` in magnitude (its squared lengths would overflow)."""
    big = float(np.abs(V).max()) if V.size else 0.0
    if big > MAX_COORDINATE:
        raise InputError(path, f"coordinates as large as {big:.3g} overflow squared lengths "
                         f"(each must stay within +-{MAX_COORDINATE:.0e})")


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


def _require_readable_file(path: str) -> None:
    if not os.path.exists(path):
        raise InputError(path, "no such file")
    if os.path.isdir(path):
        raise InputError(path, "is a directory, not a mesh file")


def _read_bytes(path: str) -> bytes:
    _require_readable_file(path)
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from exc


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
        ply = PlyData.read(io.BytesIO(data))
    except Exception as exc:  # plyfile raises several types for malformed data
        raise InputError(path, f"unparseable PLY: {_one_line(exc)}") from exc
    names = [e.name for e in ply.elements]
    if "vertex" not in names:
        raise InputError(path, "PLY has no 'vertex' element")
    vert = ply["vertex"].data
    for axis in "xyz":
        if axis not in vert.dtype.names:
            raise InputError(path, f"PLY vertex element has no '{axis}' property")
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
        F, polys = _fan_triangulate(faces)
        if polys == 0:
            ffields = {
                n: np.asarray(fdata[n], dtype=np.float64)
                for n in fdata.dtype.names
                if n != key and fdata.dtype[n].shape == () and fdata.dtype[n].kind in "fiub"
            }
    return Mesh(V, F, vfields, ffields), polys


_OBJ_ZERO_INDEX = re.compile(rb"^[ \t]*f[ \t](?:[^\n#]*?[ \t])?0(?:/[^\s#]*)?(?=[ \t\r#]|$)", re.M)


def _parse_with_trimesh(data: bytes, fmt: str, path: str) -> tuple[Mesh, int]:
    import trimesh

    if fmt == "obj":
        data = re.sub(rb"#[^\r\n]*", b"", data)  # comments, also at the end of a v or f line
        if _OBJ_ZERO_INDEX.search(data):
            _raise_obj_index_error(data, path)  # OBJ counts from 1; trimesh would take 0 as -1
    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=fmt, process=False, force="mesh")
    except IndexError as exc:
        if fmt == "obj":
            _raise_obj_index_error(data, path)
        raise InputError(path, f"face index out of range ({_one_line(exc)})") from exc
    except Exception as exc:  # trimesh raises many types for malformed files
        msg = _one_line(exc)
        if "index" in msg.lower() and "range" in msg.lower():
            raise InputError(path, f"face index out of range ({msg})") from exc
        raise InputError(path, f"unparseable {fmt.upper()}: {msg}") from exc
    V = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    F = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    if len(F) == 0 and fmt == "obj" and re.search(rb"^[ \t]*v[ \t]", data, flags=re.M):
        raise InputError(path, "mesh has no faces (vertices only; store a point cloud as PLY)")
    if V.size == 0 and len(data.strip()) > 0 and fmt != "obj":
        raise InputError(path, f"unparseable {fmt.upper()}: no vertices could be read")
    if fmt == "off" and _off_declared_faces(data) == len(F):
        return Mesh(V, F), 0  # every stored face was a triangle
    return Mesh(V, F), _count_polygons(data, fmt)


def _off_declared_faces(data: bytes) -> int | None:
    """The face count in an OFF header, read from the first lines only."""
    tokens: list[bytes] = []
    for line in data[:4096].splitlines():
        line = line.split(b"#")[0].strip()
        if line:
            tokens.extend(line.split())
        if len(tokens) >= 3 and not tokens[0][:1].isdigit():
            break
    nums = [t for t in tokens if t[:1].isdigit()]
    try:
        return int(nums[1])
    except (IndexError, ValueError):
        return None


def _count_polygons(data: bytes, fmt: str) -> int:
    """Faces with more than three corners as stored in an OBJ or OFF file."""
    if fmt == "obj":
        four = rb"^[ \t]*f(?:[ \t]+[^\s#]+){4}"
        return len(re.findall(four, data, flags=re.M))
    if fmt == "off":
        lines = [ln for ln in data.decode("latin-1").splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
        if not lines:
            return 0
        first = lines[0].split()
        rest = first[1:] if len(first) > 1 else []
        start = 1
        if not rest:
            rest, start = lines[1].split(), 2
        try:
            nv, nf = int(rest[0]), int(rest[1])
        except (IndexError, ValueError):
            return 0
        face_lines = lines[start + nv : start + nv + nf]
        return sum(1 for ln in face_lines if ln.split() and int(ln.split()[0]) > 3)
    return 0


def _raise_obj_index_error(data: bytes, path: str) -> None:
    n_v = len(re.findall(rb"^[ \t]*v[ \t]", data, flags=re.M))
    for i, m in enumerate(re.finditer(rb"^[ \t]*f[ \t]+([^\n#]*)", data, flags=re.M)):
        for tok in m.group(1).split():
            k = int(tok.split(b"/")[0])
            if k == 0 or k > n_v or k < -n_v:
                raise InputError(
                    path,
                    f"face index out of range: face {i} references vertex {k}, "
                    f"but the file has {n_v} vertices (1-based)",
                )
    raise InputError(path, "face index out of range")


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
