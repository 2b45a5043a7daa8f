"""A wheel of the working tree installs warning-free, carries the assets and the shipped weights,
runs the paper preset, and fingerprints its code exactly as the editable install does.

One wheel build and one install per session (a module fixture). The build is offline
(``--no-build-isolation``, with the running interpreter's setuptools); the wheel goes into a
temporary venv whose site-packages reaches the running interpreter's dependencies through a .pth
file, so nothing is downloaded.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from strol_gym.benchmarks.engine.provenance import DATA_FILES, code_fingerprint

ROOT = Path(__file__).resolve().parents[1]
# what a clean clone does not have: build products, caches, venvs and results
NOT_IN_A_CLONE = shutil.ignore_patterns(
    ".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache",
    ".ruff_cache", ".mypy_cache", ".hypothesis", "results", "outputs",
)  # fmt: skip


PIP = (sys.executable, "-m", "pip")
OFFLINE = ("--no-deps", "--no-index")
PAPER_ARGS = ("paper", "--env", "robot", "--runs", "2", "--quiet", "--no-plots", "--jobs", "1")
# distutils' note under pip -v whenever pip builds (pip compiles at install time): not a finding
NOT_A_FINDING = "byte-compiling is disabled"


def _setuptools_can_build_offline() -> str | None:
    try:
        import setuptools
    except ImportError:
        return "setuptools is not installed"
    major, minor = (int(x) for x in setuptools.__version__.split(".")[:2])
    if (major, minor) < (77, 0):
        found = setuptools.__version__
        return (
            f"the offline wheel build needs setuptools>=77.0.3 (.ci/setup installs it), not {found}"
        )
    return None


def _dependency_dirs() -> list[str]:
    """The running interpreter's site-packages (from ``sys.prefix``) and the plain directories
    its .pth files add (a light venv reaches its dependencies that way), but none of its import
    hooks: the editable install's finder must not shadow the wheel."""
    site = Path(sysconfig.get_path("purelib", vars={"base": sys.prefix, "platbase": sys.prefix}))
    dirs = [str(site)]
    for pth in sorted(site.glob("*.pth")):
        for line in pth.read_text().splitlines():
            line = line.strip()
            if line and not line.startswith(("#", "import")) and Path(line).is_dir():
                dirs.append(line)
    return dirs


@pytest.fixture(scope="module")
def wheel_install(tmp_path_factory):
    reason = _setuptools_can_build_offline()
    if reason:
        pytest.skip(reason)
    tmp = tmp_path_factory.mktemp("packaging")
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=NOT_IN_A_CLONE)
    build = subprocess.run(
        [*PIP, "wheel", *OFFLINE, "--no-build-isolation", "-v", "-w", str(tmp / "dist"), str(src)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    (wheel,) = (tmp / "dist").glob("strol_gym-*.whl")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    Path(site, "_strol_deps.pth").write_text("\n".join(_dependency_dirs()) + "\n")
    install = subprocess.run(
        [*PIP, "--python", str(python), "install", "-q", *OFFLINE, str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert install.returncode == 0, install.stdout[-3000:] + install.stderr[-3000:]
    return {"build_log": build.stdout + build.stderr, "wheel": wheel, "venv": venv, "tmp": tmp}


def test_the_build_prints_no_setuptools_warning(wheel_install):
    lines = wheel_install["build_log"].splitlines()
    warnings = [ln for ln in lines if "warning" in ln.lower() and NOT_A_FINDING not in ln]
    assert not warnings, "\n".join(warnings[:20])


def test_the_wheel_carries_the_assets_and_the_pretrained_weights(wheel_install):
    names = set(zipfile.ZipFile(wheel_install["wheel"]).namelist())
    for package, suffixes in DATA_FILES.items():
        folder = ROOT.joinpath(*package.split("."))
        shipped = sorted(f.name for f in folder.iterdir() if f.name.endswith(suffixes))
        assert shipped, f"no data files in {folder}"
        for name in shipped:
            assert f"{package.replace('.', '/')}/{name}" in names
    for module in ("strol_gym/wrappers/__init__.py", "strol_gym/benchmarks/cli.py"):
        assert module in names
    for page in ("index.html", "page.js", "page.css"):  # strol-bench serve's page
        assert f"strol_gym/benchmarks/serve/static/{page}" in names
    assert not any(n.startswith(("wrappers/", "benchmarks/")) for n in names), (
        "wrappers and benchmarks must install under the strol_gym namespace"
    )
    lab = [n for n in names if n.startswith("lab/") or "/lab/" in n]
    assert not lab, f"the lab is not installed, yet the wheel holds {lab[:5]}"


def test_the_wheel_carries_licence_citation_changelog_and_no_pickled_weights(wheel_install):
    wheel = zipfile.ZipFile(wheel_install["wheel"])
    names = wheel.namelist()
    info = next(n.split("/")[0] for n in names if n.endswith(".dist-info/METADATA"))
    data = info.replace(".dist-info", ".data")
    assert f"{info}/licenses/LICENSE" in names
    for doc in ("CITATION.cff", "CHANGELOG.md"):
        assert f"{data}/data/share/doc/strol-gym/{doc}" in names, doc
        assert wheel.read(f"{data}/data/share/doc/strol-gym/{doc}") == (ROOT / doc).read_bytes()
    assert not [n for n in names if n.endswith((".pt", ".pth", ".pkl"))]
    assert {n.split("/")[0] for n in names} == {"strol_gym", info, data}  # no lab/, no results/
    weights = [n for n in names if n.startswith("strol_gym/pretrained/")]
    assert len([n for n in weights if n.endswith(".safetensors")]) >= 6
    assert {n.rsplit(".", 1)[1] for n in weights} == {"safetensors", "json"}
    metadata = wheel.read(f"{info}/METADATA").decode().splitlines()
    assert "License-Expression: MIT" in metadata and "License-File: LICENSE" in metadata
    assert not [ln for ln in metadata if ln.startswith(("License:", "Classifier: License"))]
    core = [ln for ln in metadata if ln.startswith("Requires-Dist:") and "extra ==" not in ln]
    assert core and not [ln for ln in core if "==" in ln]  # ranges, not pins
    required = {re.split(r"[<>=!~; ]", ln.removeprefix("Requires-Dist: "))[0] for ln in core}
    assert {"numpy", "torch", "gymnasium", "mujoco", "safetensors"} <= required
    # the lean core: the benchmark's, the adapter's and the video's packages are extras
    assert not required & {"matplotlib", "tqdm", "imageio", "stable-baselines3", "numba", "ray"}


def test_editable_and_wheel_installs_have_one_code_fingerprint(wheel_install):
    python = wheel_install["venv"] / "bin" / "python"
    probe = subprocess.run(
        [str(python), "-c", "import strol_gym, strol_gym.benchmarks.engine.runner as r; "
         "print(strol_gym.__file__); print(r.code_fingerprint())"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=wheel_install["tmp"],
    )  # fmt: skip
    assert probe.returncode == 0, probe.stderr[-3000:]
    where, fingerprint = probe.stdout.split()
    assert Path(where).is_relative_to(wheel_install["venv"]), f"imported {where}, not the wheel"
    assert fingerprint == code_fingerprint()


def test_the_installed_wheel_runs_the_paper_preset(wheel_install):
    venv, out = wheel_install["venv"], wheel_install["tmp"] / "paper"
    run = subprocess.run(
        [str(venv / "bin" / "strol-bench"), *PAPER_ARGS, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=wheel_install["tmp"],
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    meta = json.loads((out / "meta.json").read_text())
    assert meta["status"] == "complete"
    assert meta["extra"]["code"] == code_fingerprint()


def test_the_test_extra_carries_setuptools_with_the_bound_the_build_needs():
    """This file imports setuptools (>= 77.0.3 for the PEP 639 license expression):
    ``pip install .[test]`` must bring it, at the bound pyproject.toml's build requirement and
    the skip check use."""
    import configparser
    import tomllib

    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    test_extra = cfg["options.extras_require"]["test"].split()
    build_requires = tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]
    assert "setuptools>=77.0.3" in build_requires["requires"]
    assert "setuptools>=77.0.3" in test_extra
