"""Reproducible synthetic noise for meshes, point clouds and animations
(the standard denoising benchmark protocol)."""

from geoproc.perturb.noise import (
    DIRECTIONS,
    NoiseSpec,
    noise_scale,
    outlier_flags,
    perturb_positions,
    point_cloud_normals,
    vertex_normals,
)

__all__ = ["DIRECTIONS", "NoiseSpec", "noise_scale", "outlier_flags", "perturb_positions", "point_cloud_normals",
           "vertex_normals"]
