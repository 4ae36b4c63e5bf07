"""Shared mesh pieces: the :class:`Mesh` container, readers, writers, clean-up,
topology queries and input validation used by every subcommand.

Names are loaded on first use (PEP 562): reading and writing a mesh needs
neither scipy nor the compiled topology kernels, so the command line can read
(or refuse) its input before it loads them.
"""

from __future__ import annotations

from geoproc.lazy import lazy_attributes

_NAMES = {
    "LoadLog": "mesh",
    "Mesh": "mesh",
    "clean_mesh": "clean",
    "load_mesh": "read",
    "mesh_info": "info",
    "mesh_to_bytes": "write",
    "read_mesh_bytes": "read",
    "save_mesh": "write",
}

__all__ = sorted(_NAMES)


__getattr__ = lazy_attributes(__name__, _NAMES)
