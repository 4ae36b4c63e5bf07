"""Clean and weakly noisy meshes: what the default denoiser does below the benchmark's noise.

The targets of the denoise benchmark (denoise_pairs.py) start at sigma = 0.2
mean edge lengths. Below that the noise is comparable to the fine detail of
the meshes themselves, and the noise estimate (``noise_roughness``, about
sigma for Gaussian noise along the normals) reads that detail as noise too:
the clean shared meshes read from 0.001 (teapot) to 0.054 (cow), the same as
noise of 0 to 0.05 mean edge lengths on another mesh. This table shows, for
each shared mesh perturbed as ``geoproc perturb --noise sigma --seed 1`` does
(sigma 0 is the clean mesh itself), the roughness read, the input's mean
normal angle to the clean mesh (theta, degrees), the default ``guided``
result's, and the faces the result turns more than 90 degrees from the clean
mesh that the input had not.

Usage: python bench/denoise_weak.py  (about three minutes on two cores)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"

from geoproc.denoise import denoise_mesh  # noqa: E402
from geoproc.denoise.metrics import flipped_faces, mean_normal_angle_deg, new_flipped_faces  # noqa: E402
from geoproc.mesh import load_mesh  # noqa: E402
from geoproc.perturb import NoiseSpec, perturb_positions  # noqa: E402

MESHES = [("meshes", "cow.obj"), ("meshes", "bunny.off"), ("meshes", "spot.obj"), ("meshes", "fertility.off"),
          ("meshes", "armadillo.obj"), ("meshes", "camelhead.off"), ("meshes", "teapot.obj"),
          ("meshes", "fandisk.off"), ("denoise", "SharpSphere0.3/Original.obj"), ("denoise", "Bunny0.2/Original.obj")]
SIGMAS = (0.0, 0.02, 0.03, 0.05, 0.1)


def weak_noise_table() -> str:
    """Markdown table, one row per (mesh, sigma)."""
    rows = ["| mesh | faces | σ | roughness read | θ input ° | θ result ° | new flips |",
            "|---|---:|---:|---:|---:|---:|---:|"]
    for folder, name in MESHES:
        m = load_mesh(SHARED / folder / name)
        for sigma in SIGMAS:
            if sigma > 0:
                Vn, _ = perturb_positions(m.V, m.F, NoiseSpec(sigma=sigma), np.random.default_rng(1))
            else:
                Vn = m.V
            res = denoise_mesh(Vn, m.F)
            before = flipped_faces(Vn, m.F, m.V)
            label = name if folder == "meshes" else name.split("/")[0] + " clean"
            rows.append(f"| {label} | {len(m.F)} | {sigma:g} | {res.info['noise_roughness']:.3f} "
                        f"| {mean_normal_angle_deg(Vn, m.F, m.V):.2f} | {mean_normal_angle_deg(res.V, m.F, m.V):.2f} "
                        f"| {new_flipped_faces(res.V, m.F, m.V, before)} |")
            print(rows[-1], flush=True)
    return "\n".join(rows)


def main() -> int:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()  # --help, and no stray arguments
    if not (SHARED / "meshes").is_dir():
        print(f"shared data not found at {SHARED}; nothing to benchmark")
        return 0
    text = "## denoise on clean and weakly noisy meshes (default guided)\n\n" + weak_noise_table()
    out = ROOT / "out" / "bench"
    out.mkdir(parents=True, exist_ok=True)
    (out / "denoise_weak.md").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
