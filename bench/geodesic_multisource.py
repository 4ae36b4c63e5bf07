"""Several sources at once: geoproc heat and log-heat against potpourri3d.

On five meshes from ../shared/data/meshes, random source sets of 2, 3, 5 and
10 vertices (``--sets`` of each size, seed 11), each solved in one call:
potpourri3d's ``compute_distance_multisource``, geoproc's heat and log-heat
(t = h^2). Errors are mean |d - d*| / max d* against libigl's exact geodesics
to the nearest source, averaged over the sets; "lower than pp3d" counts the
sets where geoproc's error is below potpourri3d's.

Usage: python bench/geodesic_multisource.py [--sets K] [--out out/bench]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data" / "meshes"
MESHES = ["spot.obj", "bunny.off", "fandisk.off", "camelhead.off", "fertility.off"]
SIZES = (2, 3, 5, 10)


def mesh_rows(name: str, sets: int, rng: np.random.Generator) -> list[str]:
    """Markdown rows (one per method) for one mesh."""
    import potpourri3d as pp3d

    import geoproc.geodesic as gd
    from geoproc.mesh import load_mesh

    m = load_mesh(SHARED / name)
    h = gd.mean_edge_length(m.V, m.F)
    heat = gd.HeatMethodSolver(m.V, m.F, h * h)
    log_heat = gd.LogHeatSolver(m.V, m.F, h * h)
    peer = pp3d.MeshHeatMethodDistanceSolver(m.V, m.F)
    errs: dict[str, list[float]] = {"potpourri3d": [], "geoproc heat": [], "geoproc log-heat": []}
    for k in SIZES:
        for _ in range(sets):
            src = rng.choice(len(m.V), k, replace=False)
            ref = gd.exact_geodesic_distance(m.V, m.F, src)
            found = {"potpourri3d": peer.compute_distance_multisource(src),
                     "geoproc heat": np.maximum(heat.solve(src)[0], 0.0),
                     "geoproc log-heat": np.maximum(log_heat.solve(src)[0], 0.0)}
            for label, d in found.items():
                errs[label].append(gd.compare_to_reference(d, ref)["mean_relative_error"])
    base = np.array(errs["potpourri3d"])
    rows = []
    for label, e in errs.items():
        e = np.array(e)
        lower = "" if label == "potpourri3d" else f"{int((e < base).sum())} / {len(e)}"
        rows.append(f"| {name} | {len(m.V)} | {label} | {e.mean():.4f} | {e.mean() / base.mean():.2f} | {lower} |")
    return rows


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", type=int, default=6, help="source sets of each size (default 6)")
    ap.add_argument("--out", default=str(ROOT / "out" / "bench"))
    args = ap.parse_args(argv)
    if not SHARED.is_dir():
        print(f"skipped: {SHARED} is absent")
        return 0
    rng = np.random.default_rng(11)
    lines = [f"#### Several sources in one solve ({args.sets} random sets each of {', '.join(map(str, SIZES))} "
             "sources per mesh, seed 11, t = h^2)", "",
             "| mesh | vertices | method | mean error | vs pp3d | sets lower than pp3d |",
             "|---|---:|---|---:|---:|---:|"]
    for name in MESHES:
        lines += mesh_rows(name, args.sets, rng)
        print(lines[-3], lines[-2], lines[-1], sep="\n", flush=True)
    text = "\n".join(lines)
    os.makedirs(args.out, exist_ok=True)
    Path(args.out, "geodesic_multisource.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
