"""Where the files shipped with the package are: ``config/`` (scenes, problems, parameters, RViz) and ``test/data/``.

Installed (``colcon build``, ``pip install``), setup.py puts them under ``<prefix>/share/physics_mapper/``
of the prefix the Python package is installed in (``<prefix>/lib/python3.X/site-packages``);
in a source checkout (an editable install, ``make venv``) they are the checkout's own folders.
Either way the relative paths are the same, so commands find them from any working directory.
"""

from __future__ import annotations

from pathlib import Path

from ament_index_python import PackageNotFoundError, get_package_share_path

from physics_mapper.model.errors import InputError

PACKAGE = "physics_mapper"
#: The package's Python folder, ``.../physics_mapper``.
_PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: How far above the package's folder an install prefix can be: ``<prefix>/local/lib/python3.X/dist-packages``.
_PREFIX_DEPTH = 4


def ament_share_directory(package: str) -> Path | None:
    """The package's share directory in the ament index (``AMENT_PREFIX_PATH``), or None."""
    try:
        return get_package_share_path(package, print_warning=False)
    except (PackageNotFoundError, ValueError, OSError):  # a name it cannot hold; no AMENT_PREFIX_PATH at all
        return None


def share_directory() -> Path:
    """The folder holding ``package.xml``, ``config/`` and ``test/data/`` of the running installation.

    A source checkout first (the package's parent folder holds ``package.xml``), then the ament
    index's share directory (a colcon or apt install), then ``<prefix>/share/physics_mapper`` of the
    install prefixes above the package's folder: a pip install into a virtual environment is in no
    ament index unless ``AMENT_PREFIX_PATH`` names it. Raises InputError, naming where it looked,
    for an installation without its share directory.
    """
    checkout = _PACKAGE_DIR.parent
    if (checkout / "package.xml").is_file() and (checkout / "config").is_dir():
        return checkout
    indexed = ament_share_directory(PACKAGE)
    if indexed is not None and (indexed / "package.xml").is_file():
        return indexed
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
