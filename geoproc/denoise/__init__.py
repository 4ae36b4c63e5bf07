"""Feature-preserving denoising: meshes (bilateral, guided and RPCA-guided normal
filtering with the vertex update; l1 feature identification), point-cloud
outliers (RPCA on neighbourhoods; on the animation matrix for time-varying
clouds) and animations (RPCA on the vertices' normal heights over time, or on
the stacked per-frame face normals as in the review's Algorithm 4).

Names are loaded on first use (PEP 562), so importing the package does not
compile or load the numba kernels until a function is needed.
"""

from __future__ import annotations

# the function ``rpca`` shares its name with its module: bound here, it is not
# replaced by the submodule when another module imports geoproc.denoise.rpca
# (numpy only, so importing the package stays light)
from geoproc.denoise.rpca import RPCAResult as RPCAResult
from geoproc.denoise.rpca import rpca as rpca
from geoproc.lazy import lazy_attributes

METHODS = ("bilateral", "guided", "rpca")
DEFAULT_METHOD = "guided"
COHERENCE = ("heights", "normals")  # what --dynamic makes coherent over time; the first is the default

_NAMES = {
    "DenoiseParams": "params",
    "DenoiseResult": "mesh_denoise",
    "denoise_mesh": "mesh_denoise",
    "FaceConnectivity": "connectivity",
    "face_connectivity": "connectivity",
    "median_dihedral_deg": "mesh_denoise",
    "denoise_errors": "metrics",
    "denoise_animation": "dynamic",
    "L1FeatureResult": "features",
    "l1_feature_vertices": "features",
    "AnimationOutlierResult": "outliers",
    "OutlierResult": "outliers",
    "detection_scores": "outliers",
    "rpca_animation_outliers": "outliers",
    "rpca_outliers": "outliers",
}

__all__ = ["COHERENCE", "DEFAULT_METHOD", "METHODS", "RPCAResult", "rpca", *_NAMES]


__getattr__ = lazy_attributes(__name__, _NAMES)
