"""Write a :class:`Mesh` as PLY (named properties), OBJ, OFF or STL.

PLY keeps positions as ``double`` and each field in its type (``uchar`` colours
stay ``uchar``; computed fields are ``double``), so a round trip is exact. A
field of shape (n, k) is written as k scalar properties ``name_0`` ...
``name_{k-1}``. OBJ, OFF and STL carry geometry only.
"""

from __future__ import annotations

import os

import numpy as np

from geoproc.errors import UsageError
from geoproc.fileio import file_extension, file_kind, write_bytes_atomic
from geoproc.mesh.mesh import Mesh

WRITE_FORMATS = ("ply", "obj", "off", "stl")
STL_MAX_COORDINATE = float(np.finfo(np.float32).max)  # STL stores float32


def save_mesh(path: str | os.PathLike, mesh: Mesh, binary: bool = True) -> None:
    """Write ``mesh`` to ``path`` atomically; the format follows the extension.

    Parameters
    ----------
    path : str or PathLike
        ``.ply``, ``.obj``, ``.off`` or ``.stl``.
    mesh : Mesh
    binary : bool
        Binary little-endian PLY (default) or ASCII PLY.
    """
    write_bytes_atomic(path, mesh_to_bytes(mesh, write_format(path), binary=binary))


def write_format(path: str | os.PathLike) -> str:
    """The mesh format to write ``path`` in, from its extension (one of
    :data:`WRITE_FORMATS`; binary PLY for a device or FIFO without one, such as
    ``/dev/null``); UsageError for any other extension."""
    ext = file_extension(path)
    if not ext and file_kind(os.fspath(path)) == "other":  # /dev/null, a FIFO, a link to /dev/stdout: binary PLY
        return "ply"
    if not ext:
        raise UsageError(f"{os.fspath(path)}: no file extension to choose the format by; use .ply, .obj, .off "
                         "or .stl")
    if ext not in WRITE_FORMATS:
        raise UsageError(f"{os.fspath(path)}: cannot write '.{ext}'; use .ply, .obj, .off or .stl")
    return ext


def mesh_to_bytes(mesh: Mesh, fmt: str = "ply", binary: bool = True) -> bytes:
    """Serialize ``mesh`` in format ``fmt`` (``ply``, ``obj``, ``off``, ``stl``)."""
    if fmt == "ply":
        return _ply_bytes(mesh, binary)
    if fmt == "obj":
        return _obj_bytes(mesh)
    if fmt == "off":
        return _off_bytes(mesh)
    if fmt == "stl":
        import trimesh

        return trimesh.Trimesh(mesh.V, mesh.F, process=False).export(file_type="stl")
    raise UsageError(f"unknown mesh format '{fmt}'")


PLY_TYPES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint",
             "f4": "float", "f8": "double"}
"""PLY's scalar types by numpy type code (little-endian as written)."""


def _ply_column(values: np.ndarray) -> np.ndarray:
    """A field's values in a type PLY stores: as they are when PLY has their
    type (bool as uchar), else float64 (int64, float16, ...)."""
    a = np.asarray(values)
    if a.dtype.kind == "b":
        return a.astype(np.uint8)
    code = f"{a.dtype.kind}{a.dtype.itemsize}"
    return a if code in PLY_TYPES else a.astype(np.float64)


def _ply_type(a: np.ndarray) -> str:
    """The PLY type name of a column made by :func:`_ply_column`."""
    return PLY_TYPES[f"{a.dtype.kind}{a.dtype.itemsize}"]


def _ascii_format(a: np.ndarray) -> str:
    """A printf format that gives the column's values back exactly: integers
    as integers, float32 in 9 significant digits, float64 in 18."""
    return "%d" if a.dtype.kind in "iu" else ("%.9g" if a.dtype.itemsize == 4 else "%.18g")


def _scalar_columns(fields: dict[str, np.ndarray], n: int) -> list[tuple[str, np.ndarray]]:
    cols = []
    for name, values in fields.items():
        a = _ply_column(values).reshape(n, -1)
        if a.shape[1] == 1:
            cols.append((name, a[:, 0]))
        else:
            cols.extend((f"{name}_{j}", a[:, j]) for j in range(a.shape[1]))
    return cols


def _ply_bytes(mesh: Mesh, binary: bool) -> bytes:
    """PLY with positions as ``double``, fields in their types (:func:`_ply_column`)
    and faces as ``uchar``-counted ``int`` index lists (the layout plyfile
    writes for these arrays), built vectorized: one structured array for
    binary, one formatting pass for ASCII."""
    n, m = len(mesh.V), len(mesh.F)
    vcols = [("x", mesh.V[:, 0]), ("y", mesh.V[:, 1]), ("z", mesh.V[:, 2])]
    vcols += _scalar_columns(mesh.vertex_fields, n)
    fcols = _scalar_columns(mesh.face_fields, m) if m else []
    head = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", "comment geoproc",
            f"element vertex {n}"] + [f"property {_ply_type(v)} {name}" for name, v in vcols]
    if m:
        head += [f"element face {m}", "property list uchar int vertex_indices"]
        head += [f"property {_ply_type(v)} {name}" for name, v in fcols]
    header = ("\n".join(head) + "\nend_header\n").encode("ascii")
    if binary:
        vdata = np.empty(n, dtype=[(name, v.dtype.newbyteorder("<")) for name, v in vcols])
        for name, values in vcols:
            vdata[name] = values
        parts = [header, vdata.tobytes()]
        if m:
            fdata = np.empty(m, dtype=[("\nlen", "u1"), ("vertex_indices", "<i4", (3,))]
                             + [(name, v.dtype.newbyteorder("<")) for name, v in fcols])
            fdata["\nlen"] = 3
            fdata["vertex_indices"] = mesh.F
            for name, values in fcols:
                fdata[name] = values
            parts.append(fdata.tobytes())
        return b"".join(parts)
    # every PLY type widens to float64 exactly, so the rows are formatted from one float64 array
    text = _fmt_rows(np.column_stack([values for _, values in vcols]).astype(np.float64), "",
                     [_ascii_format(v) for _, v in vcols])
    if m:  # counts and indices stay integers (their digits, as plyfile writes them)
        faces = np.column_stack([np.full(m, 3), mesh.F])
        if fcols:
            faces = np.column_stack([faces.astype(object)] + [np.asarray(v, dtype=object) for _, v in fcols])
        text += _fmt_rows(faces, "", ["%d"] * 4 + [_ascii_format(v) for _, v in fcols])
    return header + text.encode("ascii")


def _fmt_rows(a: np.ndarray, prefix: str, fmt: str | list[str]) -> str:
    """Rows of the 2-D array ``a``: ``prefix``, the values formatted by ``fmt``
    (one format for every column, or a list of one per column) and separated
    by spaces, a newline; in one formatting pass."""
    if len(a) == 0:
        return ""
    row = prefix + " ".join([fmt] * a.shape[1] if isinstance(fmt, str) else fmt) + "\n"
    return (row * len(a)) % tuple(a.ravel().tolist())


def _obj_bytes(mesh: Mesh) -> bytes:
    text = "# geoproc\n" + _fmt_rows(mesh.V, "v ", "%.17g") + _fmt_rows(mesh.F + 1, "f ", "%d")
    return text.encode()


def _off_bytes(mesh: Mesh) -> bytes:
    head = f"OFF\n{len(mesh.V)} {len(mesh.F)} 0\n"
    faces = np.column_stack([np.full(len(mesh.F), 3), mesh.F]) if len(mesh.F) else mesh.F
    return (head + _fmt_rows(mesh.V, "", "%.17g") + _fmt_rows(faces, "", "%d")).encode()
