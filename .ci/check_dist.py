"""The release leg's check of what a release uploads (``python .ci/check_dist.py DIST``): one
sdist and one wheel of setup.cfg's version; the wheel installs the strol_gym package alone and
carries the licence, CITATION.cff and CHANGELOG.md; neither holds a lab/ file, a results folder
or pickled weights (the shipped ĝ weights are safetensors)."""

import configparser
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PICKLED = (".pt", ".pth", ".pkl", ".pickle", ".ckpt")


def fail(message: str) -> None:
    sys.exit(f"error: {message}")


cfg = configparser.ConfigParser()
cfg.read(ROOT / "setup.cfg")
version = cfg["metadata"]["version"]
dist = Path(sys.argv[1])
wheels, sdists = sorted(dist.glob("*.whl")), sorted(dist.glob("*.tar.gz"))
if [w.name for w in wheels] != [f"strol_gym-{version}-py3-none-any.whl"]:
    fail(f"expected one wheel of version {version} in {dist}, found {[w.name for w in wheels]}")
if [s.name for s in sdists] != [f"strol_gym-{version}.tar.gz"]:
    fail(f"expected one sdist of version {version} in {dist}, found {[s.name for s in sdists]}")

wheel = zipfile.ZipFile(wheels[0]).namelist()
info, data = f"strol_gym-{version}.dist-info", f"strol_gym-{version}.data"
tops = {n.split("/")[0] for n in wheel}
if tops != {"strol_gym", info, data}:
    fail(f"the wheel installs more than the strol_gym package: {sorted(tops)}")
for name in (
    f"{info}/licenses/LICENSE",
    f"{data}/data/share/doc/strol-gym/CITATION.cff",
    f"{data}/data/share/doc/strol-gym/CHANGELOG.md",
):
    if name not in wheel:
        fail(f"the wheel lacks {name}")

# Every data file the package reads at run time is in the wheel: each file git tracks under the
# installed trees that is not a module (a fit, a scene, weights, the page), under its import path.
ROOMS = {
    "strol_gym/": "strol_gym/",
    "benchmarks/": "strol_gym/benchmarks/",
    "wrappers/": "strol_gym/wrappers/",
}
tracked = subprocess.run(
    ["git", "ls-files", *ROOMS], cwd=ROOT, capture_output=True, text=True, check=True
).stdout.split()
for name in tracked:
    if name.endswith(".py"):
        continue
    room = next(r for r in ROOMS if name.startswith(r))
    if ROOMS[room] + name[len(room) :] not in wheel:
        fail(f"the wheel lacks the data file {name} (setup.cfg's [options.package_data])")

sdist = [n.split("/", 1)[1] for n in tarfile.open(sdists[0]).getnames() if "/" in n]
for name in ("LICENSE", "CITATION.cff", "CHANGELOG.md", "PKG-INFO", "setup.cfg"):
    if name not in sdist:
        fail(f"the sdist lacks {name}")

for kind, names in (("wheel", wheel), ("sdist", sdist)):
    if bad := [n for n in names if n.startswith(("lab/", "results/")) or "/lab/" in n]:
        fail(f"the {kind} holds lab or results files: {bad[:5]}")
    if bad := [n for n in names if n.endswith(PICKLED)]:
        fail(f"the {kind} holds pickled weights: {bad[:5]}")
print(f"{wheels[0].name}: {len(wheel)} files; {sdists[0].name}: {len(sdist)} files; both checked")
