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

from geoproc.mesh.text_numbers import (
    INTEGER_CHARS,
    parse_plain,
    plainly_spelled,
    token_begins,
    token_ends,
    tokens_per_line,
)

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


MAX_COUNT_DIGITS = 20
"""Digits of the longest element count a PLY header may give (2^64 has 20);
longer ones are refused (:mod:`geoproc.mesh.read`) before ``int()``, which
counts leading zeros and stops at 4300 digits."""


def parse_ply_header(data: bytes) -> tuple[str, list[PlyElementHeader], int] | None:
    """The format (``ascii``, ``binary_little_endian``, ``binary_big_endian``),
    the elements and the offset of the body, or None when the header is not
    one this module reads (a list property outside the face element, two
    lists in one element, a list count of a float type, duplicate names, an
    unknown type, CR line ends).
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
        elif (words[0] == "element" and len(words) == 3 and words[2].isdigit()
              and len(words[2].lstrip("0")) <= MAX_COUNT_DIGITS):
            elements.append([words[1], int(words[2].lstrip("0") or "0"), [], None, None])  # (int() counts zeros)
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in PLY_TYPES:
            elements[-1][2].append((words[2], PLY_TYPES[words[1]]))
        elif (words[0] == "property" and elements and len(words) == 5 and words[1] == "list"
              and words[2] in PLY_TYPES and PLY_TYPES[words[2]][0] in "iu"
              and words[3] in PLY_TYPES and elements[-1][3] is None
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
    """Structured dtype of one row of ``e`` with its list ``k`` items long
    (the list a (k,) sub-array after its count field ``"\nlen"``)."""
    return np.dtype([(field, order + code, (span,)) if field == e.list_name else (field, order + code)
                     for field, span, code in _column_types(e, k)])


def smallest_row_bytes(e: PlyElementHeader) -> int:
    """Bytes of the shortest binary row of ``e``: its scalars and its list's
    count, the list empty."""
    return _row_dtype(e, "<", 0).itemsize


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


def _ascii_lines(body: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """(start, end) byte offsets of the body's lines, split at ``\n`` (the
    newline that ends the last row makes no line of its own), or None when
    the body is not plain ASCII text: a byte above 127, or a control
    character other than tab, line feed, vertical tab, form feed and
    carriage return (which separate values)."""
    arr = np.frombuffer(body, dtype=np.uint8)
    if arr.size and (arr.max() > 126 or ((arr < 32) & ((arr < 9) | (arr > 13))).any()):
        return None
    newlines = np.flatnonzero(arr == 10)
    start = np.concatenate(([0], newlines + 1))
    end = np.concatenate((newlines, [len(arr)]))
    if start[-1] == len(arr):
        start, end = start[:-1], end[:-1]
    return start, end


def _ascii_element(body: bytes, lines: tuple[np.ndarray, np.ndarray], start: int, e: PlyElementHeader):
    """(rows, next line) of element ``e`` from line ``start`` of the body, or
    None when its lists differ in length, a row is not on one line of its
    own, a value is no number of its type (plyfile parses ``int`` values as
    integers: only digits and a sign), or the lines run out.

    The element's lines are parsed as one block: the tokens per line are
    counted from the byte classes, and the numbers are read at once."""
    line_start, line_end = lines
    stop = start + e.count
    if stop > len(line_start) or (e.count and not e.scalars):  # (rows of no properties: plyfile's to read)
        return None
    k = 0
    if e.list_types is not None and e.count:
        before = next(i for i, (n, _) in enumerate(e.scalars) if n is None)
        first = body[line_start[start]:line_end[start]].split()
        try:
            k = int(first[before]) if len(first) > before else -1
        except ValueError:
            return None
        if k < 0:
            return None
    width = len(e.scalars) + (k if e.list_types is not None else 0)
    dtype = _row_dtype(e, "=", k)
    if not e.count:
        return _without_counts(np.empty(0, dtype=dtype), e, k), stop
    lo, hi = int(line_start[start]), int(line_end[stop - 1])
    block = np.frombuffer(body, dtype=np.uint8, count=hi - lo, offset=lo)
    space, begins = token_begins(block)
    if len(begins) != e.count * width:
        return None
    if (tokens_per_line(begins, line_start[start:stop] - lo, hi - lo) != width).any():
        return None  # a row not on one line of its own
    columns = _column_types(e, k)
    integer = np.concatenate([np.full(span, np.dtype(code).kind != "f") for _, span, code in columns])
    if not _tokens_fit(block, space, begins, integer, width):
        return None
    # integers only (the faces) read as int64: several times faster than floats
    values = parse_plain(body[lo:hi], space, begins, bool(integer.all()))
    if values is None:
        return None
    table = values.reshape(e.count, width)
    rows = np.empty(e.count, dtype=dtype)
    col = 0
    for field, span, code in columns:
        typed = _typed(table[:, col:col + span], np.dtype(code))
        if typed is None:
            return None
        rows[field] = typed.reshape(rows[field].shape)
        col += span
    rows = _without_counts(rows, e, k)
    return None if rows is None else (rows, stop)


def _column_types(e: PlyElementHeader, k: int) -> list[tuple[str, int, str]]:
    """(field, columns, type code) of each property of ``e`` in file order,
    with the list as its count and its ``k`` items."""
    out = []
    for name, code in e.scalars:
        if name is None:
            out += [("\nlen", 1, e.list_types[0]), (e.list_name, k, e.list_types[1])]
        else:
            out.append((name, 1, code))
    return out


def _tokens_fit(block: np.ndarray, space: np.ndarray, begins: np.ndarray, integer: np.ndarray,
                width: int) -> bool:
    """Whether every token of the block is made of the characters of its
    column's type: digits and a sign for integer columns (``integer``, one
    flag per column), those plus ``.``, exponents and the letters of nan and
    inf for float columns."""
    if not plainly_spelled(block, space, integer=False):
        return False
    if not integer.any():
        return True
    if integer.all():
        return plainly_spelled(block, space, integer=True)
    ends = token_ends(space)
    mine = np.tile(integer, len(begins) // width)
    bounds = np.column_stack((begins[mine], ends[mine])).reshape(-1)
    other = np.append(~INTEGER_CHARS[block], False)  # one more byte: the last token may end the block
    bad = np.logical_or.reduceat(other, bounds)[::2]  # over [begin, end) of each integer token
    return not bad.any()


def _without_counts(rows: np.ndarray, e: PlyElementHeader, k: int) -> np.ndarray | None:
    """``rows`` of ``e`` without the list's count field, or None when a row's
    count is not ``k`` (lists of mixed lengths)."""
    if e.list_types is None:
        return rows
    if e.count and not (rows["\nlen"] == k).all():
        return None
    return rows[[n for n in rows.dtype.names if n != "\nlen"]]


def _typed(values: np.ndarray, dtype: np.dtype) -> np.ndarray | None:
    """int64 or float64 values read from text as ``dtype``, or None where an
    integer type cannot hold one exactly (beyond its range, or a float64
    reading beyond 2**53, where it may have rounded)."""
    if dtype.kind == "f":  # beyond float32's range becomes inf, as a binary float32 file would hold
        with np.errstate(over="ignore"):
            return values.astype(dtype)
    info = np.iinfo(dtype)
    low, high = (max(info.min, -2**53), min(info.max, 2**53)) if values.dtype.kind == "f" else (info.min, info.max)
    if values.size and (values.min() < low or values.max() > high):
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
        body = data[offset:]
        lines = _ascii_lines(body)
        if lines is None:
            return None
        pos = 0
        for e in elements:
            got = _ascii_element(body, lines, pos, e)
            if got is None:
                return None
            out[e.name], pos = got
        rest = body[lines[0][pos]:] if pos < len(lines[0]) else b""
        return None if rest.strip() else out  # blank lines may end the file; anything else goes to plyfile
    order = "<" if fmt == "binary_little_endian" else ">"
    for e in elements:
        got = _binary_element(data, offset, e, order)
        if got is None:
            return None
        out[e.name], offset = got
    return out if offset == len(data) else None
