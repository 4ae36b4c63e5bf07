"""Walk on Spheres / Walk on Stars for 2D Laplace problems, with harmonic control variates.

Modules: :mod:`.domain` (polygonal domains), :mod:`.mask` (mask images traced to
loops), :mod:`.expression` (safe boundary expressions), :mod:`.program` (their
numba evaluation inside walks), :mod:`.closest`
(closest-point grid), :mod:`.rng` (per-point random streams), :mod:`.walk`
(Walk on Spheres), :mod:`.wost` (Walk on Stars), :mod:`.kernels` (Green and
segment-angle kernels), :mod:`.fit` (ridge fit), :mod:`.npass` (Adam
refinement), :mod:`.solve` (grid solver), :mod:`.images` (EXR/PNG output).
"""

from geoproc.lazy import lazy_attributes

# loaded on first use: parsing an expression needs no numba, reading a domain does
_NAMES = {
    "Domain": "domain",
    "build_domain": "domain",
    "load_domain_json": "domain",
    "Expression": "expression",
    "evaluate": "expression",
    "parse_expression": "expression",
    "load_domain": "load",
    "load_domain_mask": "mask",
    "trace_mask": "mask",
    "METHODS": "solve",
    "WosResult": "solve",
    "grid_over": "solve",
    "solve_laplace": "solve",
}

__all__ = sorted(_NAMES)

__getattr__ = lazy_attributes(__name__, _NAMES)
