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
    from_file = data is None
    if from_file:
        data = read_input_bytes(path, "domain file")
    if data[:64].lstrip().startswith(b"{") or (from_file and path.lower().endswith(".json")):
        return load_domain_json(path, data)
    if not from_file:
        raise InputError(path, "not a JSON domain (a mask image must be given as a file)")
    return load_domain_mask(path)
