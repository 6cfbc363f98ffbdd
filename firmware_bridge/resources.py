"""Data files shipped in the package: the drive's EDS, the feedforward DBC, the C handler.

Found through :mod:`importlib.resources`, so they come from wherever the package
is installed (editable checkout or wheel; ``[tool.setuptools.package-data]``
lists them). cantools, canopen and gcc read from paths, so the package must be
installed as files, not imported from a zip archive.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from gms_comp.errors import BusError


def packaged_path(name: str) -> Path:
    """Path of the data file or folder ``name`` inside the installed package."""
    resource = resources.files(__package__).joinpath(name)
    if not isinstance(resource, Path) or not resource.exists():
        raise BusError(
            f"firmware_bridge: packaged file {name!r} not found in the installation "
            f"({resource}); reinstall the package from files, not a zip"
        )
    return resource
