"""geoproc.lazy: package names loaded on first use."""

from __future__ import annotations

import subprocess
import sys

import pytest

from geoproc.lazy import lazy_attributes


def test_a_name_is_imported_from_its_module_on_first_use():
    get = lazy_attributes("geoproc.mesh", {"Mesh": "mesh", "gone": "mesh"})
    from geoproc.mesh.mesh import Mesh

    assert get("Mesh") is Mesh
    with pytest.raises(AttributeError, match="'geoproc.mesh' has no attribute 'other'"):
        get("other")
    with pytest.raises(AttributeError):  # listed, but the module has no such name
        get("gone")


def test_importing_the_packages_loads_no_numerical_module():
    code = ("import sys, geoproc.mesh, geoproc.denoise, geoproc.geodesic, geoproc.perturb; "
            "print(sorted(m for m in ('scipy', 'numba', 'igl', 'trimesh') if m in sys.modules))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and p.stdout.strip() == "[]", (p.stdout, p.stderr)
