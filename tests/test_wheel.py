"""The package as built: a wheel, installed into a fresh virtual environment outside the source tree, works.

The wheel is built from a copy of the project (nothing is written into the source tree), installed with
``--no-deps`` into a virtual environment that borrows this one's packages (NumPy, OpenCV, ...) through a
``.pth`` file, so that it costs seconds; the environment's own site-packages come first, so ``panomap`` is
the wheel's. Then ``panomap --version``, ``panomap view --help`` and ``panomap demo`` run from it, in a
folder outside the source tree, and the two web pages' static files, the bundled demo data and ``py.typed``
are read from the installed package.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

import panomap

ROOT = Path(__file__).resolve().parents[1]

# Files the package must ship beside its modules (pyproject's package-data), as paths in the wheel.
SHIPPED = [
    "panomap/py.typed",
    "panomap/data/room.json",
    "panomap/learn/static/index.html",
    "panomap/learn/static/app.js",
    "panomap/learn/static/app.css",
    "panomap/viewer/static/index.html",
    "panomap/viewer/static/viewer.js",
    "panomap/viewer/static/viewer_rig.js",
    "panomap/viewer/static/viewer.css",
]

# Run inside the installed environment: where panomap comes from, and every page's file read as the servers do.
CHECK_INSTALLED = """
import sys
from importlib import metadata, resources
from pathlib import Path

import panomap
from panomap.learn.server import LearnHandler
from panomap.viewer.server import ViewerHandler

print(Path(panomap.__file__).resolve())
assert metadata.version("panomap") == panomap.__version__, (metadata.version("panomap"), panomap.__version__)
for handler in (LearnHandler, ViewerHandler):
    for name, _type in handler.static_files.values():
        assert resources.files(handler.static_package).joinpath("static", name).read_bytes(), name
assert resources.files("panomap").joinpath("py.typed").is_file()
assert resources.files("panomap").joinpath("data", "room.json").read_bytes()
"""


def _clean_env() -> dict[str, str]:
    """This process's environment without what would put the source tree on the path."""
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "PYTHONHOME")}
    env["PYTHONNOUSERSITE"] = "1"
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh virtual environment with the wheel built from this source tree installed; its bin folder."""
    work = tmp_path_factory.mktemp("wheel")
    source = work / "source"
    source.mkdir()
    shutil.copy2(ROOT / "pyproject.toml", source)
    shutil.copy2(ROOT / "README.md", source)
    shutil.copytree(ROOT / "src", source / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    env = _clean_env()
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run([*pip, "wheel", "--no-deps", "-w", str(work / "dist"), str(source)], check=True, env=env)
    (wheel,) = (work / "dist").glob("panomap-*.whl")
    assert wheel.name.startswith(f"panomap-{panomap.__version__}-")
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
    missing = [name for name in SHIPPED if name not in names]
    assert not missing, f"the wheel lacks {missing}"
    assert not any(name.startswith(("tests/", "docs/", "bench/")) for name in names)

    venv = work / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, env=env)
    python = venv / "bin" / "python"
    site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    ).stdout.strip()
    # This environment's packages after the new one's own (a .pth's folders are not searched for .pth files:
    # an editable install of the source tree here stays out).
    borrowed = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    Path(site, "borrowed.pth").write_text("".join(f"{path}\n" for path in sorted(borrowed)))
    subprocess.run(
        [*pip, "--python", str(python), "install", "--no-deps", "--no-index", str(wheel)], check=True, env=env
    )
    return venv / "bin"


def _run(command: list[str], cwd: Path) -> str:
    result = subprocess.run(command, cwd=cwd, capture_output=True, text=True, env=_clean_env(), timeout=240)
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


@pytest.mark.slow
def test_the_wheel_installs_and_runs_outside_the_source_tree(installed: Path, tmp_path: Path) -> None:
    """The installed package is the wheel's (not the source tree), ships its data, and its commands run."""
    where = Path(_run([str(installed / "python"), "-c", CHECK_INSTALLED], tmp_path).strip())
    assert installed.parent in where.parents and ROOT not in where.parents
    assert (
        _run([str(installed / "panomap"), "--version"], tmp_path).strip() == f"panomap, version {panomap.__version__}"
    )
    assert "Usage: panomap view" in _run([str(installed / "panomap"), "view", "--help"], tmp_path)
    demo = _run([str(installed / "panomap"), "demo", "-o", "out"], tmp_path)
    assert "done in" in demo
    for name in ("omni.png", "table.npz", "panorama.png", "cylinder.png", "plane.png"):
        assert (tmp_path / "out" / name).is_file(), name


def test_the_version_is_written_once() -> None:
    """pyproject takes the version from ``panomap.__version__``, and the changelog records it."""
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert 'dynamic = ["version"]' in pyproject and 'attr = "panomap.__version__"' in pyproject
    assert f"## {panomap.__version__}" in (ROOT / "CHANGELOG.md").read_text()
