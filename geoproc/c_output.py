"""Keeping compiled libraries' own prints off standard output.

A command may write its result to standard output (``-o -``), so nothing else
may reach it: not even a C library's ``printf``, which bypasses Python's
``sys.stdout``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def c_stdout_silenced() -> Iterator[None]:
    """Discard what compiled code prints on file descriptor 1 inside the block
    (wurlitzer's redirect; Python's own ``print`` is not affected once the block
    ends, and standard error is left alone). Where wurlitzer does not run
    (Windows), the block runs as it is."""
    try:
        from wurlitzer import pipes
    except ImportError:  # pragma: no cover - POSIX only
        yield
        return
    sys.stdout.flush()
    with open(os.devnull, "w") as null, pipes(stdout=null, stderr=None):
        yield
