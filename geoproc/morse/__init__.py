"""Discrete Morse theory on triangle meshes: the discrete gradient of a vertex
function (ProcessLowerStars), its critical cells, lower-star persistence pairs
and the optimal topological simplification of Bauer, Lange and Wardetzky.

Every algorithm here works under one total order of the vertices: by value,
then by vertex index (:func:`vertex_order`). Ties in the values are therefore
harmless: two equal values are ordered by index, everywhere, consistently.
"""

from geoproc.morse.barycentric import BarycentricSimplification, barycentric_simplify
from geoproc.morse.complex import SurfaceComplex, surface_complex
from geoproc.morse.gradient import DiscreteGradient, discrete_gradient
from geoproc.morse.order import vertex_order
from geoproc.morse.persistence import PersistencePairs, lower_star_persistence
from geoproc.morse.pipeline import MorseSimplification, morse_simplify
from geoproc.morse.simplify import Simplification, simplify_function
from geoproc.morse.vpath import find_closed_vpath

__all__ = [
    "BarycentricSimplification",
    "DiscreteGradient",
    "MorseSimplification",
    "PersistencePairs",
    "Simplification",
    "SurfaceComplex",
    "barycentric_simplify",
    "discrete_gradient",
    "find_closed_vpath",
    "lower_star_persistence",
    "morse_simplify",
    "simplify_function",
    "surface_complex",
    "vertex_order",
]
