"""ament_python package definition: `colcon build` on a ROS machine, `pip install -e .` here."""

from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "physics_mapper"
#: Folders installed under share/physics_mapper/ with their relative paths kept, so that the commands find
#: them the same way installed or in a checkout (physics_mapper/model/shipped.py).
SHIPPED = ("config", "test/data")


def shipped_files() -> list[tuple[str, list[str]]]:
    """data_files entries: every file below the SHIPPED folders, one entry per folder."""
    folders: dict[str, list[str]] = {}
    for root in SHIPPED:
        for path in sorted(Path(root).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts:
                folders.setdefault(f"share/{PACKAGE}/{path.parent}", []).append(str(path))
    return list(folders.items())


def requirements(file_name):
    """The pinned requirements of a requirements file next to this one (comments and blank lines left out)."""
    lines = (Path(__file__).resolve().parent / file_name).read_text().splitlines()
    return [line.split("#")[0].strip() for line in lines if line.split("#")[0].strip()]


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=["physics_mapper", "physics_mapper.*", "msg_adapters", "msg_adapters.*"]),
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
    entry_points={
        "console_scripts": [
            # `ros2 run physics_mapper node` runs lib/physics_mapper/node (setup.cfg puts scripts there).
            "node = physics_mapper.commands.node:main",
            "managed_node = physics_mapper.commands.node:main_managed",
            "physics-mapper = physics_mapper.cli:main",
        ],
    },
)
