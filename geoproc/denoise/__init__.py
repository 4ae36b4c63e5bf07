"""Feature-preserving denoising: meshes (bilateral, guided and RPCA-guided normal
filtering with the vertex update), point-cloud outliers (RPCA on neighbourhoods)
and animations (RPCA on the stacked per-frame normals)."""

from geoproc.denoise.mesh_denoise import (
    DEFAULT_METHOD,
    METHODS,
    DenoiseParams,
    DenoiseResult,
    denoise_mesh,
    median_dihedral_deg,
)
from geoproc.denoise.metrics import denoise_errors
from geoproc.denoise.outliers import OutlierResult, detection_scores, rpca_outliers
from geoproc.denoise.rpca import RPCAResult, rpca

__all__ = [
    "DEFAULT_METHOD",
    "METHODS",
    "DenoiseParams",
    "DenoiseResult",
    "OutlierResult",
    "RPCAResult",
    "denoise_errors",
    "denoise_mesh",
    "detection_scores",
    "median_dihedral_deg",
    "rpca",
    "rpca_outliers",
]
