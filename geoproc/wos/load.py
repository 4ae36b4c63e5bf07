"""Read a domain: a JSON file of loops, or a mask image traced into loops."""

from __future__ import annotations

from geoproc.errors import InputError
from geoproc.fileio import read_input_bytes
from geoproc.wos.domain import Domain, load_domain_json
from geoproc.wos.mask import NoImageReader, load_domain_mask


def load_domain(path: str, data: bytes | None = None) -> Domain:
    """Load ``path``: ``.json`` (or content starting with ``{``) as loops, else a
    mask image. ``data`` is the content of ``path`` when the caller has read it
    (for ``-``, standard input, where only JSON is read); a mask image is then
    read from the file again."""
    if data is None:
        data = read_input_bytes(path, "domain file")
    # (a byte-order mark some editors write may come first: json.loads reads it)
    # (all the leading white space: JSON with more than 64 bytes of it had been refused)
    if data.removeprefix(b"\xef\xbb\xbf").lstrip()[:1] == b"{" or path.lower().endswith(".json"):
        return load_domain_json(path, data)
    if path == "-":
        raise InputError(path, "not a JSON domain (a mask image must be given as a file)")
    try:
        return load_domain_mask(path)
    except NoImageReader as exc:  # neither of the two kinds of domain
        raise InputError(path, "neither a JSON domain nor an " + exc.problem.removeprefix("not an ")) from None
