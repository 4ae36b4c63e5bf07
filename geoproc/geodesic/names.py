"""The names a caller chooses among: methods, solvers, Laplacians and where the
operators live, with each method's defaults. No numerical code, so the command
line can build its options without loading scipy or the compiled kernels."""

from __future__ import annotations

METHODS = ("exact", "heat", "varadhan", "log-splitting", "log-ode", "log-heat")
"""Geodesic methods of :func:`geoproc.geodesic.distance.geodesic_distance`."""
SOLVERS = ("lu", "newton", "cvxpy")
"""Solvers of the log-ODE step (``log-ode`` only)."""
LAPLACIANS = ("cotan", "intrinsic-delaunay")
"""Laplacians :func:`geoproc.geodesic.operators.laplacian_and_mass` builds."""
OPERATORS = ("auto", "extrinsic", "intrinsic")
"""Where heat and log-heat take their gradient, divergence and Poisson Laplacian."""

#: Laplacian each method uses unless told otherwise.
DEFAULT_LAPLACIAN = {
    "heat": "intrinsic-delaunay",  # its non-negative weights keep the heat positive (the cotan's did not, on
    # a bunny with one half twice subdivided: up to 45 times potpourri3d's error)
    "varadhan": "cotan",
    "log-splitting": "cotan",
    "log-ode": "intrinsic-delaunay",
    "log-heat": "intrinsic-delaunay",
}
#: Where heat and log-heat take gradient, divergence and the Poisson Laplacian
#: unless told otherwise: on the mesh itself, or on its intrinsic Delaunay
#: triangulation where the mesh has slivers (geoproc.geodesic.intrinsic).
DEFAULT_OPERATORS = {"heat": "auto", "log-heat": "auto"}
#: What -m heat does where its heat step falls below the smallest normal double (see
#: geoproc.geodesic.distance.geodesic_distance): solve the step again in the
#: log domain (the default, first), or keep the plain result.
HEAT_UNDERFLOW = ("log-domain", "keep")
RENDER_VIEWS = ("z", "-z", "x", "-x", "y", "-y")
"""Axes :func:`geoproc.geodesic.render.render_distance_png` looks along: the
camera on that side of the mesh (``z``: from +z, with x right and y up)."""
