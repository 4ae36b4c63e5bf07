"""Whitespace-separated numbers in ASCII mesh files, read a block at a time.

The text readers (ASCII PLY, OFF, OBJ) hold rows of numbers, one row per
line. Splitting every line in Python costs more than the parse itself at a
million rows, so a block of lines is classified byte by byte instead: token
starts give the values per line, a character check keeps to the plain
spellings (digits and a sign for integers; also a point, exponents, ``nan``
and ``inf`` for floats), and numpy reads all the numbers in one call. Callers
fall back to their line-by-line readers (which word the errors) when a block
is outside those spellings.
"""

from __future__ import annotations

import warnings

import numpy as np

SPACE = np.zeros(256, dtype=bool)
SPACE[[9, 10, 11, 12, 13, 32]] = True  # what bytes.split() splits at
INTEGER_CHARS = np.zeros(256, dtype=bool)
INTEGER_CHARS[list(b"0123456789+-")] = True
FLOAT_CHARS = INTEGER_CHARS.copy()
FLOAT_CHARS[list(b".eEnNaAiIfFtTyY")] = True  # a point, exponents, nan, inf, infinity


def token_begins(block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the tokens of a byte block start.

    Parameters
    ----------
    block : (b,) uint8 bytes.

    Returns
    -------
    space : (b,) bool, the separator bytes.
    begins : (t,) int64 offsets of the first byte of every token.
    """
    space = SPACE[block]
    begins = np.flatnonzero(~space & np.concatenate(([True], space[:-1])))
    return space, begins


def token_ends(space: np.ndarray) -> np.ndarray:
    """(t,) int64 offsets just past the last byte of every token, ``space``
    being :func:`token_begins`' separator mask of the block."""
    return np.flatnonzero(~space & np.append(space[1:], True)) + 1


def tokens_per_line(begins: np.ndarray, line_starts: np.ndarray, size: int) -> np.ndarray:
    """(l,) int64 tokens on each line, the lines starting at ``line_starts``
    (increasing byte offsets into a block of ``size`` bytes, the first 0)."""
    return np.diff(np.searchsorted(begins, np.append(line_starts, size)))


def plainly_spelled(block: np.ndarray, space: np.ndarray, integer: bool) -> bool:
    """Whether every non-space byte of the block belongs to a plain integer
    (``integer``: digits and a sign) or float (also a point, exponents, the
    letters of nan and inf) spelling; ``space`` is :func:`token_begins`' mask."""
    return bool(((INTEGER_CHARS if integer else FLOAT_CHARS)[block] | space).all())


def parse_plain(data: bytes, space: np.ndarray, begins: np.ndarray, integer: bool) -> np.ndarray | None:
    """The whitespace-separated numbers of ``data`` as int64 (``integer``) or
    float64, or None when one does not parse, an integer token is longer
    than 18 characters (it might not fit in int64, where numpy's reading
    saturates) or does not end in a digit. ``space`` and ``begins`` are :func:`token_begins` of ``data``;
    the characters must have been checked."""
    if integer and len(begins):
        ends = token_ends(space)
        if (ends - begins).max() > 18:
            return None
        last = np.frombuffer(data, dtype=np.uint8)[ends - 1]
        if ((last < 48) | (last > 57)).any():  # a sign alone, which numpy reads as 0 at the end of data
            return None
    try:
        with warnings.catch_warnings():  # numpy before 2.3 warns (and stops) where later ones raise
            warnings.simplefilter("error", DeprecationWarning)
            values = np.fromstring(data, dtype=np.int64 if integer else np.float64, sep=" ")
    except (ValueError, DeprecationWarning):  # a token that is not a number
        return None
    return values if values.size == len(begins) else None


def numbers_on_lines(lines: list, integer: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """The numbers on each line, read as one block.

    Parameters
    ----------
    lines : list of bytes, without line ends.
    integer : bool
        Integers (int64; plain digits and a sign only), else floats (float64).

    Returns
    -------
    values : (t,) the numbers of all lines in order.
    counts : (len(lines),) int64 numbers per line.
    None when a token is spelled otherwise (the caller reads line by line).
    """
    data = b"\n".join(lines)
    block = np.frombuffer(data, dtype=np.uint8)
    space, begins = token_begins(block)
    if not plainly_spelled(block, space, integer):
        return None
    line_starts = np.concatenate(([0], np.flatnonzero(block == 10) + 1)) if lines else np.zeros(0, dtype=np.int64)
    counts = tokens_per_line(begins, line_starts, len(block))
    values = parse_plain(data, space, begins, integer)
    return None if values is None else (values, counts)


def uniform_rows(lines: list, integer: bool) -> np.ndarray | None:
    """(len(lines), k) numbers when every line holds k of them, plainly
    spelled (see :func:`numbers_on_lines`); None otherwise."""
    got = numbers_on_lines(lines, integer)
    if got is None or not len(lines):
        return None
    values, counts = got
    if not (counts == counts[0]).all():
        return None
    return values.reshape(len(lines), int(counts[0]))
