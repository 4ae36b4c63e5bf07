"""geoproc: geometry-processing research methods as pure functions on numpy arrays.

The command-line interface lives in the separate package ``geoproc_cli``; nothing
in ``geoproc`` prints or reads argv.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("geoproc")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from geoproc.errors import GeoprocError, InputError, UsageError  # noqa: E402

__all__ = ["GeoprocError", "InputError", "UsageError", "__version__"]
