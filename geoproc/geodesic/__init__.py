"""Geodesic distance on triangle meshes: exact (MMP), the heat method, Varadhan's
formula on backward-Euler heat, and three log-domain heat solvers.

The entry point is :func:`geodesic_distance` (module ``distance``); each method
also has its own module (``exact``, ``heat``, ``varadhan``, ``log_ode`` with
``log_lu`` and ``log_ode_cvxpy``, ``log_splitting``, ``log_heat``), the
operators are in ``operators`` and the Poisson step in ``poisson``. Names are
imported lazily so that importing the package stays cheap.
"""

from __future__ import annotations

from geoproc.lazy import lazy_attributes

_NAMES = {
    "METHODS": "names",
    "GeodesicResult": "distance",
    "geodesic_distance": "distance",
    "compare_to_reference": "compare",
    "exact_geodesic_distance": "exact",
    "HeatMethodSolver": "heat",
    "heat_method_distance": "heat",
    "LogHeatSolver": "log_heat",
    "log_heat_distance": "log_heat",
    "LogODESolver": "log_ode",
    "log_ode_step": "log_ode",
    "log_ode_steps": "log_ode",
    "LogSplittingSolver": "log_splitting",
    "log_splitting_distance": "log_splitting",
    "varadhan_distance": "varadhan",
    "render_distance_png": "render",
    "cotan_laplacian": "operators",
    "divergence_matrix": "operators",
    "face_gradient_matrix": "operators",
    "intrinsic_delaunay_laplacian": "operators",
    "laplacian_and_mass": "operators",
    "lumped_mass": "operators",
    "mean_edge_length": "operators",
}

__all__ = sorted(_NAMES)


__getattr__ = lazy_attributes(__name__, _NAMES)
