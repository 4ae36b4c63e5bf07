"""Walk on Spheres / Walk on Stars for 2D Laplace problems, with harmonic control variates.

Modules: :mod:`.domain` (polygonal domains), :mod:`.mask` (mask images traced to
loops), :mod:`.expression` (safe boundary expressions), :mod:`.closest`
(closest-point grid), :mod:`.rng` (per-point random streams), :mod:`.walk`
(Walk on Spheres), :mod:`.wost` (Walk on Stars), :mod:`.kernels` (Green and
segment-angle kernels), :mod:`.fit` (ridge fit), :mod:`.npass` (Adam
refinement), :mod:`.solve` (grid solver), :mod:`.images` (EXR/PNG output).
"""

from geoproc.wos.domain import Domain, build_domain, load_domain_json
from geoproc.wos.expression import Expression, evaluate, parse_expression
from geoproc.wos.load import load_domain
from geoproc.wos.mask import load_domain_mask, trace_mask
from geoproc.wos.solve import METHODS, WosResult, grid_over, solve_laplace

__all__ = [
    "METHODS", "Domain", "Expression", "WosResult", "build_domain", "evaluate", "grid_over",
    "load_domain", "load_domain_json", "load_domain_mask", "parse_expression", "solve_laplace",
    "trace_mask",
]
