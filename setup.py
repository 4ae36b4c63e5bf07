"""Package discovery: the ``cli/`` folder installs as ``geoproc_cli``.

Metadata lives in pyproject.toml; this file only maps the folders, because a
top-level module named ``cli`` would collide with other distributions.
"""

from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["geoproc", "geoproc.*"])
    + ["geoproc_cli"]
    + ["geoproc_cli." + p for p in find_packages(where="cli")],
    package_dir={"geoproc_cli": "cli"},
)
