"""ament_python package definition: `colcon build` on a ROS machine, `pip install -e .` here."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "physics_mapper"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=["physics_mapper", "physics_mapper.*", "msg_adapters", "msg_adapters.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config/scenes", glob("config/scenes/*.yaml")),
        (f"share/{PACKAGE}/config/problems", glob("config/problems/*.yaml")),
        (f"share/{PACKAGE}/config/params", glob("config/params/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="physics_mapper developers",
    maintainer_email="physics-mapper@example.com",
    description="Physically consistent multi-object 3D maps from weighted pose hypotheses.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            # `ros2 run physics_mapper node` runs lib/physics_mapper/node (setup.cfg puts scripts there).
            "node = physics_mapper.ros.node:main",
            "physics-mapper = physics_mapper.cli:main",
        ],
    },
)
