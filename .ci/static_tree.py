"""Lay out the project as it is installed, for static tools (type checker, API reference).

`wrappers/` and `benchmarks/` install as `strol_gym.wrappers` and `strol_gym.benchmarks`
(setup.cfg's package_dir), which an editable install hides from static tools. This builds a
tree of symlinks in DEST where every module sits under its import name, read from setup.cfg
itself so that the mapping has one source. Usage: python .ci/static_tree.py DEST
"""

from __future__ import annotations

import configparser
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def package_dirs() -> dict[str, Path]:
    """setup.cfg's package_dir as {import name: folder}."""
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    out: dict[str, Path] = {}
    for line in cfg["options"]["package_dir"].strip().splitlines():
        name, _, folder = (part.strip() for part in line.partition("="))
        out[name] = ROOT / folder
    return out


def build(dest: Path) -> Path:
    """Symlink each mapped package into DEST under its dotted import name; returns DEST."""
    dirs = package_dirs()
    top = sorted(dirs, key=lambda n: n.count("."))
    for name in top:
        target = dest.joinpath(*name.split("."))
        if name.count(".") == 0:
            target.mkdir(parents=True, exist_ok=True)
            nested = {n.split(".")[1] for n in dirs if n.startswith(name + ".")}
            for entry in dirs[name].iterdir():
                if entry.name not in nested and entry.name != "__pycache__":
                    (target / entry.name).symlink_to(entry)
        else:
            target.symlink_to(dirs[name], target_is_directory=True)
    return dest


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python .ci/static_tree.py DEST")
    print(build(Path(sys.argv[1])))
