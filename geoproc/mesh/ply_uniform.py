"""Vectorized reading of the common PLY layout: scalar properties, and faces
whose index lists all have the same length.

plyfile reads a binary element that holds a list property row by row in
Python (about 10 s per million triangles); meshes written by geoproc, MeshLab,
trimesh or libigl store their faces as lists of one length, which one
``numpy`` view of the bytes reads at once. :func:`read_uniform_ply`
returns None for anything outside that layout (other list properties,
lists of mixed lengths, a file of another size than its header says, an
ASCII value that its declared type cannot hold), and the caller then reads
the file with plyfile, whose errors and results stay the reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# PLY type names (both spellings) -> numpy type codes, without byte order
PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
FACE_LISTS = ("vertex_indices", "vertex_index")  # the names the mesh reader accepts


@dataclass(frozen=True)
class PlyElementHeader:
    """One ``element`` of a PLY header.

    Attributes
    ----------
    name : str
    count : int
        Number of rows.
    scalars : list of (name, type code) before and after the list, in file order,
        with the list's place marked by ``None`` as name.
    list_types : (count type code, item type code) of its one list property, or None.
    list_name : str or None
    """

    name: str
    count: int
    scalars: tuple
    list_types: tuple | None = None
    list_name: str | None = None


def parse_ply_header(data: bytes) -> tuple[str, list[PlyElementHeader], int] | None:
    """The format (``ascii``, ``binary_little_endian``, ``binary_big_endian``),
    the elements and the offset of the body, or None when the header is not
    one this module reads (a list property outside the face element, two
    lists in one element, duplicate names, an unknown type, CR line ends).
    """
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0 or (end and data[end - 1:end] != b"\n"):
        return None
    try:
        lines = data[4:end].decode("ascii").split("\n")
    except UnicodeDecodeError:
        return None
    fmt = None
    elements: list[list] = []
    for line in lines:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3 and words[2] == "1.0" and fmt is None and not elements:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append([words[1], int(words[2]), [], None, None])
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in PLY_TYPES:
            elements[-1][2].append((words[2], PLY_TYPES[words[1]]))
        elif (words[0] == "property" and elements and len(words) == 5 and words[1] == "list"
              and words[2] in PLY_TYPES and words[3] in PLY_TYPES and elements[-1][3] is None
              and elements[-1][0] == "face" and words[4] in FACE_LISTS):
            elements[-1][3] = (PLY_TYPES[words[2]], PLY_TYPES[words[3]])
            elements[-1][4] = words[4]
            elements[-1][2].append((None, None))
        else:
            return None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        return None
    names = [e[0] for e in elements]
    if len(set(names)) != len(names) or "vertex" not in names:
        return None
    out = []
    for name, count, scalars, list_types, list_name in elements:
        props = [p for p, _ in scalars if p is not None] + ([list_name] if list_name else [])
        if len(set(props)) != len(props):
            return None
        out.append(PlyElementHeader(name, count, tuple(scalars), list_types, list_name))
    return fmt, out, end + len(b"end_header\n")


def _row_dtype(e: PlyElementHeader, order: str, k: int) -> np.dtype:
    """Structured dtype of one row of ``e`` with its list ``k`` items long."""
    fields = []
    for name, code in e.scalars:
        if name is None:
            fields.append(("\nlen", order + e.list_types[0]))
            fields.append((e.list_name, order + e.list_types[1], (k,)))
        else:
            fields.append((name, order + code))
    return np.dtype(fields)


def _binary_element(data: bytes, offset: int, e: PlyElementHeader, order: str):
    """(rows, next offset) of element ``e`` at ``offset``, or None when its lists
    differ in length or the data ends early."""
    k = 0
    if e.list_types is not None and e.count:
        head = _row_dtype(e, order, 0)  # the scalars before the list, then the count
        before = head.fields["\nlen"][1]
        count_type = np.dtype(order + e.list_types[0])
        if offset + before + count_type.itemsize > len(data):
            return None
        k = float(np.frombuffer(data, count_type, 1, offset + before)[0])
        item = np.dtype(e.list_types[1]).itemsize
        if not (0 <= k <= len(data) / item and k == int(k)):  # no row of that length fits the file
            return None
        k = int(k)
    dtype = _row_dtype(e, order, k)
    size = dtype.itemsize * e.count
    if offset + size > len(data):
        return None
    rows = _without_counts(np.frombuffer(data, dtype, e.count, offset), e, k)
    return None if rows is None else (rows, offset + size)


def _ascii_element(lines: list, start: int, e: PlyElementHeader):
    """(rows, next line) of element ``e`` from the body's lines, or None when
    its lists differ in length, a row is not on one line of its own, a value
    is no number of its type (plyfile parses ``int`` values as integers), or
    the lines run out."""
    stop = start + e.count
    if stop > len(lines):
        return None
    rows_text = [line.split() for line in lines[start:stop]]
    k = 0
    if e.list_types is not None and e.count:
        before = next(i for i, (n, _) in enumerate(e.scalars) if n is None)
        try:
            k = int(rows_text[0][before]) if len(rows_text[0]) > before else -1
        except ValueError:
            return None
        if k < 0:
            return None
    width = len(e.scalars) + (k if e.list_types is not None else 0)
    if any(len(r) != width for r in rows_text):
        return None
    table = np.array(rows_text, dtype=object).reshape(e.count, width)
    dtype = _row_dtype(e, "=", k)
    rows = np.empty(e.count, dtype=dtype)
    col = 0
    for name, code in e.scalars:
        if name is None:
            parts = [("\nlen", e.list_types[0], 1), (e.list_name, e.list_types[1], k)]
        else:
            parts = [(name, code, 1)]
        for field, type_code, span in parts:
            values = _typed(table[:, col:col + span], np.dtype(type_code))
            if values is None:
                return None
            rows[field] = values.reshape(rows[field].shape)
            col += span
    rows = _without_counts(rows, e, k)
    return None if rows is None else (rows, stop)


def _without_counts(rows: np.ndarray, e: PlyElementHeader, k: int) -> np.ndarray | None:
    """``rows`` of ``e`` without the list's count field, or None when a row's
    count is not ``k`` (lists of mixed lengths)."""
    if e.list_types is None:
        return rows
    if e.count and not (rows["\nlen"] == k).all():
        return None
    return rows[[n for n in rows.dtype.names if n != "\nlen"]]


def _typed(text: np.ndarray, dtype: np.dtype) -> np.ndarray | None:
    """Object array of number strings as ``dtype``, parsed as plyfile parses
    them (integers for integer types), or None where one does not parse or
    does not fit."""
    try:
        if dtype.kind == "f":
            return text.astype(np.float64).astype(dtype)
        values = text.astype(np.int64)
    except (ValueError, OverflowError):
        return None
    info = np.iinfo(dtype)
    if values.size and (values.min() < info.min or values.max() > info.max):
        return None
    return values.astype(dtype)


def read_uniform_ply(data: bytes) -> dict[str, np.ndarray] | None:
    """Every element of a PLY file as a structured array, or None.

    Parameters
    ----------
    data : bytes
        The whole file.

    Returns
    -------
    dict from element name to a (count,) structured array (fields named as
    the properties; the face list as a (count, k) sub-array), or None when
    the file is outside the layout this module reads: then read it with
    plyfile.
    """
    parsed = parse_ply_header(data)
    if parsed is None:
        return None
    fmt, elements, offset = parsed
    out: dict[str, np.ndarray] = {}
    if fmt == "ascii":
        try:
            lines = data[offset:].decode("ascii").split("\n")
        except UnicodeDecodeError:
            return None
        if lines and lines[-1] == "":
            lines.pop()  # the newline that ends the last row
        pos = 0
        for e in elements:
            got = _ascii_element(lines, pos, e)
            if got is None:
                return None
            out[e.name], pos = got
        return out if pos == len(lines) else None
    order = "<" if fmt == "binary_little_endian" else ">"
    for e in elements:
        got = _binary_element(data, offset, e, order)
        if got is None:
            return None
        out[e.name], offset = got
    return out if offset == len(data) else None
