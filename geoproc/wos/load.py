"""Read a domain: a JSON file of loops, or a mask image traced into loops."""

from __future__ import annotations

import os

from geoproc.errors import InputError
from geoproc.wos.domain import Domain, load_domain_json
from geoproc.wos.mask import load_domain_mask


def load_domain(path: str) -> Domain:
    """Load ``path``: ``.json`` (or content starting with ``{``) as loops, else a mask image."""
    if not os.path.isfile(path):
        raise InputError(path, "no such file")
    with open(path, "rb") as fh:
        head = fh.read(64).lstrip()
    if path.lower().endswith(".json") or head.startswith(b"{"):
        return load_domain_json(path)
    return load_domain_mask(path)
