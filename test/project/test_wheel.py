"""A wheel built from the tree installs ``msg_adapters/`` as ``physics_mapper.msg_adapters``, nothing else on top."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from conftest import PACKAGE, REPO, not_sources


def test_a_wheel_installs_no_top_level_package_but_physics_mapper(tmp_path: Path) -> None:
    source = tmp_path / "src"
    shutil.copytree(REPO, source, ignore=not_sources)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input"]
    built = subprocess.run(
        [*pip, "wheel", "--no-deps", "--no-build-isolation", "--wheel-dir", str(tmp_path / "dist"), str(source)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert built.returncode == 0, built.stdout + built.stderr
    (wheel,) = (tmp_path / "dist").glob("*.whl")
    target = tmp_path / "site-packages"
    installed = subprocess.run(
        [*pip, "install", "--no-deps", "--no-index", "--target", str(target), str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert installed.returncode == 0, installed.stdout + installed.stderr
    packages = sorted(path.name for path in target.iterdir() if (path / "__init__.py").is_file())
    modules = sorted(path.name for path in target.glob("*.py"))
    assert (packages, modules) == ([PACKAGE], [])
    adapters = sorted(path.name for path in (target / PACKAGE / "msg_adapters").glob("*.py"))
    assert adapters == sorted(path.name for path in (REPO / "msg_adapters").glob("*.py"))
