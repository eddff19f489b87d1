"""ament_python package definition: `colcon build` on a ROS machine, `pip install -e .` here."""

import sys
from pathlib import Path

from setuptools import find_packages, setup

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


def console_scripts():
    """``physics-mapper`` always; ``ros2 run``'s ``node`` and ``managed_node`` only for colcon.

    ``ros2 run physics_mapper node`` runs ``<prefix>/lib/physics_mapper/node``, where setup.cfg puts
    the scripts of colcon's ``setup.py install`` and ``develop``. A wheel (``pip install``) would put
    them in ``bin/``, where a script named ``node`` shadows Node.js; there ``physics-mapper node`` runs it.
    """
    scripts = ["physics-mapper = physics_mapper.cli:main"]
    if {"install", "develop"} & set(sys.argv[1:]):
        scripts += [
            "node = physics_mapper.commands.node:main",
            "managed_node = physics_mapper.commands.node:main_managed",
        ]
    return scripts


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
    entry_points={"console_scripts": console_scripts()},
)
