"""Mesh loading and `info` against trimesh and libigl on the shared meshes.

Run: ``make bench`` or ``.venv/bin/python bench/mesh_io.py``. Prints a markdown
table of median wall-clock times (5 runs) and ratios to the fastest peer loader.
geoproc's load includes validation and the clean-up (merge + unreferenced);
trimesh is timed with process=True (which merges too), libigl with
read_triangle_mesh (no clean-up).
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import igl
import trimesh

from geoproc.mesh import load_mesh, mesh_info

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"


def median_time(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main() -> int:
    if not SHARED.is_dir():
        print(f"skipped: {SHARED} not found")
        return 0
    print("| mesh | geoproc load s | trimesh load s | libigl load s | load ratio (geoproc / fastest peer) "
          "| geoproc info s | trimesh topology s |")
    print("|---|---|---|---|---|---|---|")
    for path in sorted(SHARED.iterdir()):
        ours = median_time(lambda p=path: load_mesh(p))
        tm = median_time(lambda p=path: trimesh.load(p, process=True, force="mesh"))
        il = median_time(lambda p=path: igl.read_triangle_mesh(str(p)))
        mesh = load_mesh(path)
        info = median_time(lambda m=mesh: mesh_info(m))

        def trimesh_topology(m=mesh):
            t = trimesh.Trimesh(m.V, m.F, process=False)
            return (t.euler_number, t.is_watertight, t.is_winding_consistent,
                    len(t.edges_unique), len(trimesh.graph.connected_components(t.edges)))

        tt = median_time(trimesh_topology)
        print(f"| {path.name} | {ours:.4f} | {tm:.4f} | {il:.4f} | {ours / min(tm, il):.2f} | {info:.4f} | {tt:.4f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
