"""Shared mesh pieces: the :class:`Mesh` container, readers, writers, clean-up,
topology queries and input validation used by every subcommand."""

from geoproc.mesh.clean import clean_mesh
from geoproc.mesh.info import mesh_info
from geoproc.mesh.mesh import LoadLog, Mesh
from geoproc.mesh.read import load_mesh, read_mesh_bytes
from geoproc.mesh.write import mesh_to_bytes, save_mesh

__all__ = [
    "LoadLog",
    "Mesh",
    "clean_mesh",
    "load_mesh",
    "mesh_info",
    "mesh_to_bytes",
    "read_mesh_bytes",
    "save_mesh",
]
