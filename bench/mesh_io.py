"""Mesh loading and `info` against trimesh and libigl on the shared meshes,
then PLY reading and writing at pipeline size.

Run: ``make bench`` or ``.venv/bin/python bench/mesh_io.py``. Prints markdown
tables of median wall-clock times and ratios to the fastest peer.

1. The shared meshes (5 runs each): geoproc's load includes validation and the
   clean-up (merge + unreferenced); trimesh is timed with process=True (which
   merges too), libigl with read_triangle_mesh (no clean-up).
2. PLY, the format subcommands hand to each other: armadillo.obj upsampled by
   libigl (``igl.upsample``, 4 and 16 times the faces), written with a
   per-vertex field as geoproc writes it (binary and ASCII), then read back
   (3 runs each for binary files). geoproc's load (validation, clean-up, fields) against
   trimesh (process=False), libigl and plyfile (the element parse alone: the
   reader geoproc used before its vectorized path); writing against trimesh's
   export and plyfile's writer. The ASCII files and plyfile's columns are
   read once (they take seconds to minutes).
3. OFF and OBJ at the larger size (3 runs each): geoproc's load against
   trimesh (process=False) and libigl.
"""

from __future__ import annotations

import argparse
import io
import statistics
import sys
import tempfile
import time
from pathlib import Path

import igl
import numpy as np
import trimesh
from plyfile import PlyData, PlyElement

from geoproc.mesh import Mesh, load_mesh, mesh_info, mesh_to_bytes

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"


def median_time(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def plyfile_bytes(mesh: Mesh, binary: bool) -> bytes:
    """The same file written by plyfile's writer (doubles, uchar/int face lists)."""
    names = ["x", "y", "z", *mesh.vertex_fields]
    vdata = np.empty(len(mesh.V), dtype=[(n, "f8") for n in names])
    for j, n in enumerate("xyz"):
        vdata[n] = mesh.V[:, j]
    for n, values in mesh.vertex_fields.items():
        vdata[n] = values
    fdata = np.empty(len(mesh.F), dtype=[("vertex_indices", "i4", (3,))])
    fdata["vertex_indices"] = mesh.F
    elements = [PlyElement.describe(vdata, "vertex"),
                PlyElement.describe(fdata, "face", len_types={"vertex_indices": "u1"})]
    buf = io.BytesIO()
    PlyData(elements, text=not binary, byte_order="<").write(buf)
    return buf.getvalue()


def ply_table() -> None:
    base = load_mesh(SHARED / "armadillo.obj")
    V, F = base.V, base.F
    print("\n| PLY | faces | MB | geoproc load s | trimesh s | libigl s | plyfile parse s | load ratio "
          "(geoproc / fastest peer) | geoproc write s | trimesh write s | plyfile write s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for level in (1, 2):
            V, F = igl.upsample(V, F)
            mesh = Mesh(V, F, {"distance": np.linalg.norm(V - V.mean(axis=0), axis=1)}, {})
            for binary in (True, False):
                path = Path(tmp) / f"arma{level}{'b' if binary else 'a'}.ply"
                data = mesh_to_bytes(mesh, "ply", binary=binary)
                path.write_bytes(data)
                repeat = 3 if binary else 1
                ours = median_time(lambda p=path: load_mesh(p), repeat)
                tm = median_time(lambda p=path: trimesh.load(p, process=False, force="mesh"), repeat)
                il = median_time(lambda p=path: igl.read_triangle_mesh(str(p)), repeat)
                pf = median_time(lambda d=data: PlyData.read(io.BytesIO(d)), 1)
                w = median_time(lambda m=mesh, b=binary: mesh_to_bytes(m, "ply", binary=b), repeat)
                tm_mesh = trimesh.Trimesh(V, F, process=False)
                encoding = "binary" if binary else "ascii"
                tw = median_time(lambda t=tm_mesh, e=encoding: t.export(file_type="ply", encoding=e), repeat)
                pw = median_time(lambda m=mesh, b=binary: plyfile_bytes(m, b), 1)
                print(f"| armadillo x{4 ** level} {'binary' if binary else 'ASCII'} | {len(F)} | "
                      f"{len(data) / 1e6:.1f} | {ours:.2f} | {tm:.2f} | {il:.2f} | {pf:.2f} | "
                      f"{ours / min(tm, il):.2f} | {w:.2f} | {tw:.2f} | {pw:.2f} |", flush=True)


def text_table(repeat: int = 3) -> None:
    """OFF and OBJ at pipeline size: armadillo upsampled to 16 times its faces,
    written by geoproc, loaded by geoproc (validation and clean-up included),
    libigl and trimesh (process=False); median of ``repeat`` runs."""
    base = load_mesh(SHARED / "armadillo.obj")
    V, F = igl.upsample(*igl.upsample(base.V, base.F))
    print("\n| text format | faces | MB | geoproc load s | trimesh s | libigl s "
          "| load ratio (geoproc / fastest peer) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in ("off", "obj"):
            path = Path(tmp) / f"arma16.{fmt}"
            data = mesh_to_bytes(Mesh(V, F, {}, {}), fmt)
            path.write_bytes(data)
            ours = median_time(lambda p=path: load_mesh(p), repeat)
            tm = median_time(lambda p=path: trimesh.load(p, process=False, force="mesh"), repeat)
            il = median_time(lambda p=path: igl.read_triangle_mesh(str(p)), repeat)
            print(f"| armadillo x16 {fmt.upper()} | {len(F)} | {len(data) / 1e6:.1f} | {ours:.2f} | {tm:.2f} | "
                  f"{il:.2f} | {ours / min(tm, il):.2f} |", flush=True)


def main() -> int:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()  # --help, and no stray arguments
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
    ply_table()
    text_table()
    return 0


if __name__ == "__main__":
    sys.exit(main())
