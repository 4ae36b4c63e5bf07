"""Read a domain: a JSON file of loops, or a mask image traced into loops."""

from __future__ import annotations

from geoproc.fileio import read_input_bytes
from geoproc.wos.domain import Domain, load_domain_json
from geoproc.wos.mask import load_domain_mask


def load_domain(path: str) -> Domain:
    """Load ``path``: ``.json`` (or content starting with ``{``) as loops, else a mask image."""
    data = read_input_bytes(path, "domain file")
    if path.lower().endswith(".json") or data[:64].lstrip().startswith(b"{"):
        return load_domain_json(path, data)
    return load_domain_mask(path)
