"""ament_python package definition: `colcon build` on a ROS machine, `pip install -e .` here.

``ros2 run physics_mapper node`` runs ``<prefix>/lib/physics_mapper/node``. Console scripts cannot
be put there by every kind of build: setup.cfg's ``[install]``/``[develop]`` script dirs move them
for ``setup.py install`` and ``develop`` (colcon), but a wheel (pip, any PEP 517 build) puts them
in ``bin/``, where a script named ``node`` shadows Node.js. So ``node`` and ``managed_node`` are
data files of ``lib/physics_mapper/`` (``scripts/``, executable, ``#!/usr/bin/env python3``: the
``python3`` of the sourced ROS environment), the same for every build; the one console script,
``physics-mapper``, has a name of its own wherever it lands.
"""

import os
import string
from pathlib import Path

from setuptools import Command, find_packages, setup

PACKAGE = "physics_mapper"
#: The top-level folder of message adapters, installed as the subpackage physics_mapper.msg_adapters.
ADAPTERS = "msg_adapters"
ADAPTER_PACKAGES = [f"{PACKAGE}.{name}" for name in find_packages(include=[ADAPTERS, f"{ADAPTERS}.*"])]
#: Folders installed under share/physics_mapper/ with their relative paths kept, so that the commands find
#: them the same way installed or in a checkout (physics_mapper/model/shipped.py).
SHIPPED = ("config", "test/data", "benchmarks")


def shipped_files() -> list[tuple[str, list[str]]]:
    """data_files entries: every file below the SHIPPED folders, one entry per folder."""
    folders: dict[str, list[str]] = {}
    for root in SHIPPED:
        for path in sorted(Path(root).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts:
                folders.setdefault(f"share/{PACKAGE}/{path.parent}", []).append(str(path))
    return list(folders.items())


#: ``ros2 run``'s executables, installed as data into ``lib/physics_mapper/`` by every kind of build.
ROS2_RUN_SCRIPTS = ("scripts/node", "scripts/managed_node")


class SymlinkDevelop(Command):
    """``setup.py develop`` as ``colcon build --symlink-install`` calls it, for setuptools >= 80.

    colcon runs ``setup.py develop --editable --build-directory DIR --no-deps`` in its build folder
    (where it has symlinked setup.py, setup.cfg and the packages), and ``develop --uninstall`` to
    undo it; setuptools 80 turned ``develop`` into a call to ``pip install -e`` without these
    options (colcon/colcon-core#696: "option --editable not recognized"). This command does what
    the old one did for colcon: the egg-info beside the symlinked packages (on colcon's
    ``PYTHONPATH``; it holds the entry points the scripts load) and the entry scripts, written by
    ``install_scripts`` (as for ``setup.py install``) into setup.cfg's ``[develop] script_dir``.
    colcon itself symlinks the data files and puts the build folder on ``PYTHONPATH``.
    """

    description = "colcon's symlink install: egg-info in place and the entry scripts"
    user_options = [
        ("editable", "e", "accepted for colcon (the packages are used in place)"),
        ("build-directory=", "b", "accepted for colcon (nothing is built)"),
        ("no-deps", "N", "accepted for colcon (dependencies are never installed)"),
        ("uninstall", "u", "remove the entry scripts"),
        ("script-dir=", "s", "folder of the entry scripts ($base: the installation prefix)"),
    ]
    boolean_options = ["editable", "no-deps", "uninstall"]

    def initialize_options(self):
        self.editable = self.no_deps = self.uninstall = False
        self.build_directory = self.script_dir = None

    def finalize_options(self):
        if self.script_dir is not None:
            base = self.get_finalized_command("install").install_base
            self.script_dir = string.Template(self.script_dir).substitute(base=base)

    def run(self):
        self.run_command("egg_info")
        scripts = self.reinitialize_command("install_scripts")
        scripts.install_dir = self.script_dir
        scripts.ensure_finalized()
        if self.uninstall:
            for name in self.distribution.entry_points["console_scripts"]:
                script = os.path.join(scripts.install_dir, name.split("=")[0].strip())
                if os.path.exists(script):
                    os.remove(script)
            return
        self.run_command("install_scripts")


def requirements(file_name):
    """The pinned requirements of a requirements file next to this one (comments and blank lines left out)."""
    lines = (Path(__file__).resolve().parent / file_name).read_text().splitlines()
    return [line.split("#")[0].strip() for line in lines if line.split("#")[0].strip()]


setup(
    name=PACKAGE,
    version="0.1.0",
    # msg_adapters/ sits beside physics_mapper/ in the source tree and is installed inside its namespace, as
    # physics_mapper.msg_adapters: no package of a generic name lands at the top of site-packages. (The link
    # physics_mapper/msg_adapters -> ../msg_adapters is for tools that know no package_dir: mypy, editors.)
    packages=[
        *find_packages(include=[PACKAGE, f"{PACKAGE}.*"], exclude=[f"{PACKAGE}.{ADAPTERS}", f"{PACKAGE}.{ADAPTERS}.*"]),
        *ADAPTER_PACKAGES,
    ],
    package_dir={f"{PACKAGE}.{ADAPTERS}": ADAPTERS},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", [str(path) for path in sorted(Path("launch").glob("*.launch.py"))]),
        (f"lib/{PACKAGE}", list(ROS2_RUN_SCRIPTS)),
        *shipped_files(),
    ],
    install_requires=["setuptools"],
    # Optional: Ray for `evaluate`/`sweep --ray` (pip install -e '.[ray]').
    extras_require={"ray": requirements("requirements-ray.txt")},
    zip_safe=True,
    maintainer="physics_mapper developers",
    maintainer_email="physics-mapper@example.com",
    description="Physically consistent multi-object 3D maps from weighted pose hypotheses.",
    license="Apache-2.0",
    # The command line; setup.cfg puts it in lib/physics_mapper for colcon (``ros2 run physics_mapper
    # physics-mapper``), a wheel in bin/ (``physics-mapper`` on PATH).
    entry_points={"console_scripts": ["physics-mapper = physics_mapper.cli:main"]},
    cmdclass={"develop": SymlinkDevelop},
)
