"""Where the files shipped with the package are: ``config/`` (scenes, problems, parameters, RViz) and ``test/data/``.

Installed (``colcon build``, ``pip install``), setup.py puts them under ``<prefix>/share/physics_mapper/``
of the prefix the Python package is installed in (``<prefix>/lib/python3.X/site-packages``);
in a source checkout (an editable install, ``make venv``) they are the checkout's own folders.
Either way the relative paths are the same, so commands find them from any working directory.
"""

from __future__ import annotations

from pathlib import Path

from physics_mapper.model.errors import InputError

PACKAGE = "physics_mapper"
#: The package's Python folder, ``.../physics_mapper``.
_PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: How far above the package's folder an install prefix can be: ``<prefix>/local/lib/python3.X/dist-packages``.
_PREFIX_DEPTH = 4


def share_directory() -> Path:
    """The folder holding ``package.xml``, ``config/`` and ``test/data/`` of the running installation.

    A source checkout first (the package's parent folder holds ``package.xml``), then
    ``<prefix>/share/physics_mapper`` of the install prefixes above the package's folder. Raises
    InputError, naming where it looked, for an installation without its share directory.
    """
    checkout = _PACKAGE_DIR.parent
    if (checkout / "package.xml").is_file() and (checkout / "config").is_dir():
        return checkout
    prefixes = list(_PACKAGE_DIR.parents)[1 : _PREFIX_DEPTH + 1]
    for prefix in prefixes:
        share = prefix / "share" / PACKAGE
        if (share / "package.xml").is_file():
            return share
    looked = ", ".join(str(prefix / "share" / PACKAGE) for prefix in prefixes)
    raise InputError(f"the shipped files of {PACKAGE} are not installed (looked in {checkout}, {looked})")


def shipped_path(relative: str) -> Path:
    """A shipped file or folder, e.g. ``shipped_path("config/scenes/pyramid.yaml")`` (it need not exist)."""
    return share_directory() / relative
