"""Typed errors shared by every algorithm and reader.

The command line maps :class:`InputError` and :class:`UsageError` to exit code 2
and prints them as one line, ``error: <file>: <problem>``.
"""

from __future__ import annotations


class GeoprocError(Exception):
    """Base class of every error geoproc raises on purpose."""


class InputError(GeoprocError):
    """Bad input data: unreadable, malformed or unsuitable for the method.

    Parameters
    ----------
    path : str or None
        The file the problem is in (``"-"`` for standard input), or None when the
        problem is not tied to one file.
    problem : str
        One line saying what is wrong, without the path.
    """

    def __init__(self, path: str | None, problem: str):
        self.path = None if path is None else str(path)
        self.problem = problem
        super().__init__(self.line())

    def line(self) -> str:
        """The one-line message, ``<file>: <problem>`` (or just the problem)."""
        return self.problem if self.path is None else f"{self.path}: {self.problem}"


def frame_error(path: str | None, t: int, problem: str, frame_files: list[str] | None = None) -> InputError:
    """The :class:`InputError` for a problem in frame ``t`` of an animation: named
    by the frame's own file when it was read from a folder (``frame_files``, one
    per frame), else ``path: frame t: problem``."""
    if frame_files:
        return InputError(frame_files[t], problem)
    return InputError(path, f"frame {t}: {problem}")


class UsageError(GeoprocError):
    """Bad parameters or option values (exit code 2)."""


def shown_number(x: float) -> str:
    """``x`` for a message, to every digit it has: Python's shortest text that
    reads back as ``x``, without a trailing ``.0`` (``400``, ``180.0000001``).
    ``%g`` keeps six digits, so a value just past a bound read as the bound
    (``--feature-angle 180: must be within [0, 180]``)."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message, or its type's name when the
    message is empty (for one-line errors that quote a library's message)."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
