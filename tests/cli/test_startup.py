"""What the command line loads before it has work to do.

``--help``, ``--version``, option errors and inputs refused on reading must not
wait for scipy, numba's kernels, libigl, trimesh or pymeshlab: together they
took about a second of every such call. Each check runs a fresh interpreter
and lists the heavy modules it imported (a module count, not a wall-clock
threshold).
"""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

HEAVY = ("scipy", "scipy.optimize", "numba", "igl", "trimesh", "pymeshlab", "matplotlib", "cvxpy")

_PROBE = """
import atexit, sys
heavy = {heavy!r}
atexit.register(lambda: print("LOADED", sorted(m for m in heavy if m in sys.modules)))
import geoproc_cli.main as main
sys.argv = ["geoproc", *{args!r}]
main.main()
"""


def heavy_modules_loaded(*args: str) -> tuple[int, list[str], str]:
    """(exit code, heavy modules imported, stderr) of ``geoproc ARGS`` in a fresh interpreter."""
    code = _PROBE.format(heavy=HEAVY, args=[str(a) for a in args])
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("LOADED")][-1]
    return p.returncode, ast.literal_eval(line.removeprefix("LOADED ")), p.stderr


def test_importing_the_application_loads_no_heavy_module():
    code = (f"import sys, geoproc_cli.main; print(sorted(m for m in {HEAVY!r} if m in sys.modules))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and p.stdout.strip() == "[]", (p.stdout, p.stderr)


@pytest.mark.parametrize(("args", "refusal"), [
    (("--version",), None),
    (("denoise", "--help"), None),
    (("geodesic", "{missing}", "-s", "0", "-o", "{out}.ply"), "no such file"),
    (("denoise", "{missing}", "-o", "{out}.ply"), "no such file"),
    (("denoise", "{fixtures}/nan.ply", "-o", "{out}.ply"), "non-finite coordinates"),
    (("denoise", "{fixtures}/points.ply", "-o", "{out}.ply"), "is a point cloud"),
    (("denoise", "{fixtures}/torus.ply", "--outliers", "--k", "2", "-o", "{out}.ply"), "--k 2"),
    (("geodesic", "{fixtures}/out_of_range.obj", "-s", "0", "-o", "{out}.ply"), "face index out of range"),
    (("info", "{fixtures}/truncated.ply"), "but only 100 bytes follow it"),
    (("morse-simplify", "{fixtures}/empty.obj", "-f", "z", "-p", "0.1", "-o", "{out}.ply"), "has no faces"),
    (("perturb", "{fixtures}/torus.ply", "--noise", "-1", "--seed", "1", "-o", "{out}.ply"), "--noise -1"),
    (("wos-solve", "{missing}", "--boundary", "x", "-o", "{out}.png"), ".exr"),
    (("wos-solve", "{missing}", "--boundary", "x", "-o", "{out}.exr"), "no such file"),
    (("wos-solve", "{missing}", "--boundary", "x+", "-o", "{out}.exr"), "not a valid expression"),
    (("info", "{fixtures}/torus.ply", "--check", "genuss==1"), "did you mean 'genus'"),
])
def test_refusals_before_the_work_load_no_heavy_module(args, refusal, fixture_dir, tmp_path):
    filled = [a.format(missing=tmp_path / "missing.ply", out=tmp_path / "o", fixtures=fixture_dir) for a in args]
    code, loaded, err = heavy_modules_loaded(*filled)
    if refusal is None:
        assert code == 0, err
    else:
        assert code == 2 and err.startswith("error:") and err.count("\n") == 1 and refusal in err, err
    assert loaded == [], (filled, loaded, err)
    assert not list(tmp_path.glob("o*")), "a refused run wrote output"


def test_work_loads_what_it_needs(fixture_dir, tmp_path):
    # the probe sees the heavy modules once a command does its work
    code, loaded, err = heavy_modules_loaded("denoise", fixture_dir / "torus.ply", "-o", tmp_path / "d.ply", "-q")
    assert code == 0, err
    assert "numba" in loaded and "scipy" in loaded


def test_info_on_a_small_mesh_runs_without_numba(fixture_dir):
    # below COMPILED_FANS_FROM corners the vertex fans are counted by sorting:
    # numba's set-up (about 0.7 s) would cost more than the count itself
    code, loaded, err = heavy_modules_loaded("info", fixture_dir / "torus.ply", "-q")
    assert code == 0, err
    assert "scipy" in loaded and "numba" not in loaded, loaded


def test_heat_geodesics_run_without_numba(fixture_dir, tmp_path):
    # numba (about 0.25 s to import) serves the log methods only; heat loaded it
    # through an exception class imported from the log-ODE module
    code, loaded, err = heavy_modules_loaded("geodesic", fixture_dir / "torus.ply", "-s", "0",
                                             "-o", tmp_path / "d.ply", "-q")
    assert code == 0, err
    assert "scipy" in loaded and "numba" not in loaded, loaded


def test_morse_simplify_loads_the_milp_solver_only_for_a_window(fixture_dir, tmp_path):
    # scipy.optimize (about 0.45 s to import) serves the exact windows, which a
    # smooth field on the torus does not need
    code, loaded, err = heavy_modules_loaded("morse-simplify", fixture_dir / "torus.ply", "-f", "z", "-p", "0.1",
                                             "--relative", "-o", tmp_path / "m.ply", "-q")
    assert code == 0, err
    assert "numba" in loaded and "scipy.optimize" not in loaded, loaded
