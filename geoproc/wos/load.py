"""Read a domain: a JSON file of loops, or a mask image traced into loops."""

from __future__ import annotations

from geoproc.errors import InputError
from geoproc.fileio import read_input_bytes
from geoproc.wos.domain import Domain, load_domain_json
from geoproc.wos.mask import load_domain_mask


def load_domain(path: str, data: bytes | None = None) -> Domain:
    """Load ``path``: ``.json`` (or content starting with ``{``) as loops, else a
    mask image. With ``data`` (the content of ``path``, e.g. ``-`` for standard
    input) only JSON is read."""
    if data is not None:
        if not data[:64].lstrip().startswith(b"{"):
            raise InputError(path, "not a JSON domain (a mask image must be given as a file)")
        return load_domain_json(path, data)
    data = read_input_bytes(path, "domain file")
    if path.lower().endswith(".json") or data[:64].lstrip().startswith(b"{"):
        return load_domain_json(path, data)
    return load_domain_mask(path)
