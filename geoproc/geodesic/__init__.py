"""Geodesic distance on triangle meshes: exact (MMP), the heat method, Varadhan's
formula on backward-Euler heat, and three log-domain heat solvers.

The entry point is :func:`geodesic_distance`; each method also has its own module
(``exact``, ``heat``, ``varadhan``, ``log_ode``, ``log_splitting``, ``log_heat``).
"""

from geoproc.geodesic.compare import compare_to_reference
from geoproc.geodesic.distance import METHODS, GeodesicResult, geodesic_distance
from geoproc.geodesic.exact import exact_geodesic_distance
from geoproc.geodesic.heat import HeatMethodSolver, heat_method_distance
from geoproc.geodesic.log_heat import LogHeatSolver, log_heat_distance
from geoproc.geodesic.log_ode import log_ode_step, log_ode_steps
from geoproc.geodesic.log_splitting import log_splitting_distance
from geoproc.geodesic.operators import (
    cotan_laplacian,
    divergence_matrix,
    face_gradient_matrix,
    intrinsic_delaunay_laplacian,
    laplacian_and_mass,
    lumped_mass,
    mean_edge_length,
)
from geoproc.geodesic.varadhan import varadhan_distance

__all__ = [
    "METHODS",
    "GeodesicResult",
    "HeatMethodSolver",
    "LogHeatSolver",
    "compare_to_reference",
    "cotan_laplacian",
    "divergence_matrix",
    "exact_geodesic_distance",
    "face_gradient_matrix",
    "geodesic_distance",
    "heat_method_distance",
    "intrinsic_delaunay_laplacian",
    "laplacian_and_mass",
    "log_heat_distance",
    "log_ode_step",
    "log_ode_steps",
    "log_splitting_distance",
    "lumped_mass",
    "mean_edge_length",
    "varadhan_distance",
]
