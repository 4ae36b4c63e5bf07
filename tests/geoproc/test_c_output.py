"""geoproc/c_output.py: compiled code's prints kept off standard output and standard error."""

from __future__ import annotations

import subprocess
import sys

import pytest

SCRIPT = """
import ctypes, sys
from geoproc.c_output import c_stdout_silenced
libc = ctypes.CDLL(None)
print("before", flush=True)
with c_stdout_silenced():
    libc.printf(b"from C inside\\n")
    libc.fflush(None)
libc.printf(b"from C after\\n")
libc.fflush(None)
print("after", flush=True)
sys.stderr.write("stderr kept\\n")
"""


@pytest.mark.skipif(sys.platform == "win32", reason="libc printf through ctypes, POSIX only")
def test_c_prints_inside_the_block_are_dropped_and_the_rest_kept():
    p = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stdout == "before\nfrom C after\nafter\n"
    assert p.stderr == "stderr kept\n"


STDERR_SCRIPT = """
import os, sys
from geoproc.c_output import c_stderr_silenced
sys.stderr.write("before\\n")
with c_stderr_silenced():
    os.write(2, b"from C inside\\n")
os.write(2, b"after\\n")
print("stdout kept", flush=True)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="descriptor redirection, POSIX only")
def test_stderr_writes_inside_the_block_are_dropped_and_a_closed_stderr_is_no_error():
    p = subprocess.run([sys.executable, "-c", STDERR_SCRIPT], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stderr == "before\nafter\n" and p.stdout == "stdout kept\n"
    closed = ("import os; os.close(2)\n"
              "from geoproc.c_output import c_stderr_silenced\nwith c_stderr_silenced():\n pass\n")
    p = subprocess.run([sys.executable, "-c", closed], capture_output=True, timeout=60)
    assert p.returncode == 0
