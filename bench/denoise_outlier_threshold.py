"""The default cut of ``denoise --outliers`` on static clouds against a fixed one.

The default is ``max(0.5, 3 x the median score)`` (in median point spacings).
For each cloud (bunny and fandisk: their vertices, and 20,000 and 100,000
points sampled on the surface, trimesh seed 1), outlier fraction (5 % and
20 %, within 1/50 of the diagonal) and Gaussian noise along the normals (0
and 0.3 point spacings; ``perturb``'s protocol, seed 2), the F1 of the
default cut, of the fixed cut 0.5, and of the best cut in 0.30, 0.35, ...,
1.45 (chosen with the truth: an upper bound). Prints a markdown table.

Usage: python bench/denoise_outlier_threshold.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
sys.path.insert(0, str(ROOT))

from geoproc.denoise import detection_scores, rpca_outliers  # noqa: E402
from geoproc.denoise.outliers import default_outlier_threshold  # noqa: E402
from geoproc.mesh import load_mesh  # noqa: E402
from geoproc.perturb import NoiseSpec, perturb_positions  # noqa: E402

CUTS = np.arange(0.30, 1.5, 0.05)


def clouds(mesh):
    """(label, points): the vertices, then 20,000 and 100,000 surface samples."""
    import trimesh

    yield "vertices", mesh.V
    for n in (20000, 100000):
        pts, _ = trimesh.sample.sample_surface(trimesh.Trimesh(mesh.V, mesh.F, process=False), n, seed=1)
        yield f"{n:,} samples", np.asarray(pts)


def main() -> int:
    if not (SHARED / "meshes").is_dir():
        print(f"skipped: {SHARED / 'meshes'} is not there")
        return 0
    rows = ["| cloud | points | outliers | noise | median score | default cut | F1 default | F1 at 0.5 | best F1 |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    print("\n".join(rows), flush=True)
    for name in ("bunny.off", "fandisk.off"):
        mesh = load_mesh(SHARED / "meshes" / name)
        for label, P0 in clouds(mesh):
            for fraction in (0.05, 0.2):
                for sigma in (0.0, 0.3):
                    spec = NoiseSpec(sigma=sigma, outliers=fraction, outlier_range=0.02)
                    P, flag = perturb_positions(P0, np.zeros((0, 3), dtype=np.int64), spec,
                                                np.random.default_rng(2))
                    score = rpca_outliers(P, k=16).score
                    cut = default_outlier_threshold(score)

                    def f1(c, score=score, flag=flag):
                        return detection_scores(score > c, flag > 0)["f1"]

                    rows.append(f"| {name} {label} | {len(P)} | {fraction:.0%} | {sigma} | "
                                f"{np.median(score):.3f} | {cut:.2f} | {f1(cut):.3f} | {f1(0.5):.3f} | "
                                f"{max(f1(c) for c in CUTS):.3f} |")
                    print(rows[-1], flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
