"""Which operators the heat method should use: the mesh's own (extrinsic) or the
intrinsic Delaunay triangulation's, on the shared meshes, a scan with holes, a
clean scan, and copies stretched along x (obtuse, non-Delaunay triangles
without slivers).

For each mesh: the share of the cotan Laplacian's off-diagonal weight that is
negative (``geoproc.geodesic.intrinsic.negative_weight_share``; ``auto`` goes
intrinsic from 0.05), the share of faces with an angle below 5 degrees (``auto``
goes intrinsic from 0.005), and heat's mean error |d - d*| / max d* against
libigl's exact geodesics from three random sources (seed 0), with each kind of
operators, and potpourri3d's (intrinsic, robust); then a flat grid sheared by x += s y, against the
Euclidean distance from its centre, with potpourri3d alongside.

Usage: python bench/geodesic_operators.py [--out out/bench]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"

import geoproc.geodesic as gd  # noqa: E402
from geoproc.geodesic.intrinsic import negative_weight_share, sliver_share  # noqa: E402
from geoproc.geodesic.operators import cotan_laplacian  # noqa: E402
from geoproc.mesh import load_mesh  # noqa: E402

MESHES = [("bunny.off", 1), ("fertility.off", 1), ("camelhead.off", 1), ("fandisk.off", 1), ("spot.obj", 1),
          ("armadillo.obj", 1), ("cow.obj", 1), ("denoise/real-scans/rabbit.obj", 1),
          ("denoise/Bunny0.2/Original.obj", 1),
          ("fandisk.off", 4), ("bunny.off", 3), ("fertility.off", 2), ("camelhead.off", 2)]
"""(mesh, stretch along x): a bare name is in the shared meshes folder, a path is under the shared data."""


def _error(d, exact):
    ok = np.isfinite(exact)
    return float(np.mean(np.abs(d[ok] - exact[ok])) / np.max(exact[ok]))


def mesh_rows() -> list[str]:
    import potpourri3d as pp3d

    rows = ["| mesh | vertices | negative weight share | faces below 5° | heat extrinsic % | heat intrinsic % | "
            "potpourri3d % | auto chose |", "|---|---:|---:|---:|---:|---:|---:|---|"]
    for name, stretch in MESHES:
        m = load_mesh(SHARED / name if "/" in name else SHARED / "meshes" / name)
        V = m.V.copy()
        V[:, 0] *= stretch
        h = gd.mean_edge_length(V, m.F)
        sources = np.random.default_rng(0).choice(len(V), 3, replace=False)
        exact = [gd.exact_geodesic_distance(V, m.F, np.array([s])) for s in sources]
        err = {}
        for ops in ("extrinsic", "intrinsic"):
            solver = gd.HeatMethodSolver(V, m.F, h * h, operators=ops)
            err[ops] = np.mean([_error(solver.solve([s])[0], e) for s, e in zip(sources, exact, strict=True)])
        pp = pp3d.MeshHeatMethodDistanceSolver(V, m.F)
        pp_err = np.mean([_error(pp.compute_distance(int(s)), e) for s, e in zip(sources, exact, strict=True)])
        chose = gd.HeatMethodSolver(V, m.F, h * h).operators
        label = name if stretch == 1 else f"{name} x {stretch} along x"
        rows.append(f"| {label} | {len(V)} | {negative_weight_share(cotan_laplacian(V, m.F)):.4f} | "
                    f"{sliver_share(V, m.F):.4f} | {100 * err['extrinsic']:.2f} | {100 * err['intrinsic']:.2f} | "
                    f"{100 * pp_err:.2f} | {chose} |")
        print(rows[-1], flush=True)
    return rows


def grid_rows(n: int = 41) -> list[str]:
    import potpourri3d as pp3d

    rows = ["| grid sheared by x += s y | negative weight share | heat extrinsic % | heat auto % | "
            "log-heat auto % | potpourri3d % |", "|---|---:|---:|---:|---:|---:|"]
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    F = np.r_[np.c_[a, a + 1, a + n + 1], np.c_[a, a + n + 1, a + n]]
    src = (n // 2) * n + n // 2
    for shear in (0.25, 0.5, 1.0, 2.0):
        V = np.c_[x.ravel() + shear * y.ravel(), y.ravel(), np.zeros(n * n)]
        exact = np.linalg.norm(V - V[src], axis=1)
        e = {ops: _error(gd.geodesic_distance(V, F, [src], method="heat", operators=ops).distance, exact)
             for ops in ("extrinsic", "auto")}
        lh = _error(gd.geodesic_distance(V, F, [src], method="log-heat").distance, exact)
        pp = _error(pp3d.MeshHeatMethodDistanceSolver(V, F).compute_distance(src), exact)
        rows.append(f"| s = {shear} | {negative_weight_share(cotan_laplacian(V, F)):.3f} | "
                    f"{100 * e['extrinsic']:.2f} | {100 * e['auto']:.2f} | {100 * lh:.2f} | {100 * pp:.2f} |")
        print(rows[-1], flush=True)
    return rows


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out/bench")
    args = ap.parse_args(argv)
    if not (SHARED / "meshes").is_dir():
        print(f"shared data not found at {SHARED}; nothing to benchmark")
        return 0
    text = "\n".join(["## heat: extrinsic or intrinsic operators", *mesh_rows(), "", *grid_rows()]) + "\n"
    print()
    print(text)
    out = ROOT / args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / "geodesic_operators.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
