"""Files named by ``package://<package>/<path>`` URLs, found with or without a ROS installation.

``package://<package>/<path>`` is ``<path>`` inside, in this order:

1. the package's share directory in the ament index (``ament_index_python``, over
   ``AMENT_PREFIX_PATH``: what RViz's resource retriever looks up too);
2. for ``physics_mapper`` itself, without an ament index (pip wheels only), this installation's
   shipped files (:func:`~physics_mapper.model.shipped.share_directory`: a source checkout, or
   ``<prefix>/share/physics_mapper`` of the prefix the package is installed in), which hold the
   same ``config/`` tree;
3. an installed Python package of that name, e.g. ``package://pybullet_data/objects/mug.obj``
   for the meshes that come with pybullet (used where they are, never copied).

RViz resolves ``package://`` through the ament index only, so a marker names a mesh by its
``package://`` URL when the ament index has the package, and by a ``file://`` URL of the
resolved absolute path otherwise (:func:`resource_uri`).
"""

from __future__ import annotations

import errno
import importlib.util
import os
import stat
from pathlib import Path, PurePosixPath

from physics_mapper.model.errors import InputError
from physics_mapper.model.shipped import PACKAGE, ament_share_directory, shipped_path

PACKAGE_URL = "package://"


class ResourceError(ValueError):
    """A ``package://`` URL names a package that cannot be found, or is malformed."""


def split_package_url(url: str) -> tuple[str, str]:
    """``package://pkg/a/b`` -> (``pkg``, ``a/b``); ResourceError when no package is named, or the path
    would leave the package's folder (a ``..`` part, or an absolute path)."""
    package, _, relative = url[len(PACKAGE_URL) :].partition("/")
    if not package:
        raise ResourceError(f"{url}: no package name after {PACKAGE_URL}")
    if relative.startswith("/") or ".." in PurePosixPath(relative).parts:
        raise ResourceError(f"{url}: the path must stay inside the package's folder (no '..', not absolute)")
    return package, relative


def resolve_package_url(url: str) -> Path:
    """The file a ``package://`` URL names (see the module docstring); ResourceError if the package is unknown."""
    package, relative = split_package_url(url)
    share = ament_share_directory(package)
    if share is not None:
        return share / relative
    if package == PACKAGE:
        try:
            return shipped_path(relative)
        except InputError as error:  # an installation without its share directory
            raise ResourceError(f"{url}: {error}") from None
    spec = importlib.util.find_spec(package) if package.isidentifier() else None
    if spec is not None and spec.submodule_search_locations:
        return Path(next(iter(spec.submodule_search_locations))) / relative
    raise ResourceError(f"{url}: package {package!r} is not in the ament index nor an installed Python package")


def resolve_resource(text: str, base_dir: Path | None) -> Path:
    """A file named by a path (relative to ``base_dir``, or the working directory) or a ``package://`` URL."""
    if text.startswith(PACKAGE_URL):
        return resolve_package_url(text)
    path = Path(text).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    return path


def file_problem(path: Path) -> str | None:
    """Why ``path`` is not a regular file to read, in a few words (None if it is one): ``missing file``,
    ``a symbolic link loop``, ``a part of its path is a file, not a folder``, ``not a file``."""
    try:
        mode = os.stat(path).st_mode
    except OSError as error:
        reasons = {
            errno.ENOENT: "missing file",
            errno.ELOOP: "a symbolic link loop",
            errno.ENOTDIR: "a part of its path is a file, not a folder",
        }
        return reasons.get(error.errno or 0, error.strerror or str(error))
    return None if stat.S_ISREG(mode) else "not a file"


def resource_uri(text: str, resolved: Path) -> str:
    """The URI RViz resolves to this file: the scene's ``package://`` URL if the ament index has the package, else ``file://``."""
    if text.startswith(PACKAGE_URL) and ament_share_directory(split_package_url(text)[0]) is not None:
        return text
    return resolved.resolve().as_uri()
