"""What holds across floating-point kernels: the experiments rerun under several, compared.

Runs ``strol-bench paper --env robot``, ``paper --env highway``, ``confirm`` (a reduced,
exploratory run by default) and ``study`` (reduced by default) once per kernel setting, each in
a subprocess with ``OPENBLAS_CORETYPE`` and ``ATEN_CPU_CAPABILITY`` set, then prints for every
output and setting the largest relative difference of any mean from the first setting's, and
whether any verdict changed. Settings the CPU cannot run (SkylakeX / avx512 without AVX-512)
are skipped with a note. docs/reproducibility.md quotes its output.

    python lab/checks/cross_kernel.py --out results/cross-kernel
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from strol_gym.benchmarks.engine.kernels import kernel_label
from strol_gym.files import write_text_atomic

ALPHA = 0.05
DEFAULT_SETTINGS = ("native", "Haswell:default", "Prescott:default")
"""``native`` is what this CPU picks by itself (the reference); ``CORE:CAPABILITY`` sets
OPENBLAS_CORETYPE and ATEN_CPU_CAPABILITY. Against native: torch's kernels alone, then both."""
AVX512_ONLY = {"SkylakeX", "SkylakeX:avx512", "avx512", "Cooperlake", "SapphireRapids"}


def _has_avx512() -> bool:
    try:
        return " avx512f" in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


PRESETS = {
    "avx2-cpu": {
        "OPENBLAS_CORETYPE": "Haswell",
        "ATEN_CPU_CAPABILITY": "avx2",
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "MKL_ENABLE_INSTRUCTIONS": "AVX2",
    },
}
"""Named settings: ``avx2-cpu`` makes an AVX-512 CPU compute as an AVX2 one does (OpenBLAS,
torch's ATen kernels, numpy's dispatched loops and MKL all held to AVX2; numpy ≥ 2's target
names)."""


def setting_env(setting: str) -> dict[str, str]:
    """The environment variables of a setting ("native": none; a name of ``PRESETS``)."""
    if setting == "native":
        return {}
    if setting in PRESETS:
        return dict(PRESETS[setting])
    core, _, cap = setting.partition(":")
    if not core or not cap:
        raise ValueError(
            f"--settings: each must be 'native', {', '.join(PRESETS)} or CORE:CAPABILITY, "
            f"got {setting!r}"
        )
    return {"OPENBLAS_CORETYPE": core, "ATEN_CPU_CAPABILITY": cap}


def runnable(setting: str) -> bool:
    if setting in PRESETS:
        return True
    parts = set(setting.split(":"))
    return _has_avx512() or not (parts & AVX512_ONLY)


def commands(args: argparse.Namespace) -> dict[str, tuple[list[str], str]]:
    """Output name -> (strol-bench arguments without --out, what is reduced: "" for none)."""
    common = ["--quiet", "--no-plots", "--jobs", str(args.jobs)]
    extra = {
        "paper --env robot": ["--runs", str(args.robot_runs)] if args.robot_runs else [],
        "paper --env highway": ["--runs", str(args.highway_runs)] if args.highway_runs else [],
        "confirm": ["--runs", str(args.confirm_runs), "--seed", "3100000"]
        if args.confirm_runs
        else [],
        "study": ["--users", str(args.study_users)] if args.study_users else [],
    }
    return {
        name: ([*name.split(), *common, *more], " ".join(more))
        for name, more in extra.items()
        if name.split()[0] in args.only
    }


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def means(folder: Path) -> dict[tuple[str, ...], float]:
    """Every mean of summary.csv, keyed by env, condition, learner and metric."""
    return {
        (r["env"], r["condition"], r["learner"], r["metric"]): float(r["mean"])
        for r in _rows(folder / "summary.csv")
    }


TESTS = {"t": ("p_holm", "mean_diff"), "wilcoxon": ("wilcoxon_p_holm", "hodges_lehmann")}
"""Each post-hoc test's Holm p-value and the estimate that gives its direction (stats.csv)."""


def _num(v: str | None) -> float:
    return float(v) if v not in (None, "") else math.nan


def tests(folder: Path) -> dict[tuple[str, ...], tuple[float, str]]:
    """Every post-hoc test of the folder (paired t and Wilcoxon): (test, env, condition,
    metric, learner, baseline) -> (Holm p, verdict: "lower" / "higher" / "n.s.")."""
    out: dict[tuple[str, ...], tuple[float, str]] = {}
    for r in _rows(folder / "stats.csv"):
        key = tuple(r.get(c, "") for c in ("env", "condition", "metric", "learner", "baseline"))
        for test, (p_col, est_col) in TESTS.items():
            if p_col not in r:
                continue
            p, est = _num(r[p_col]), _num(r[est_col])
            sig = math.isfinite(p) and p < ALPHA and math.isfinite(est) and est != 0
            out[(test, *key)] = (p, ("lower" if est < 0 else "higher") if sig else "n.s.")
    return out


def folder_verdicts(folder: Path) -> dict[tuple[str, ...], str]:
    """Every verdict of the folder: each post-hoc test's (significant, direction), paired t and
    Wilcoxon, and the confirmatory or H3 verdicts where the output has them."""
    out: dict[tuple[str, ...], str] = {k: v for k, (_, v) in tests(folder).items()}
    if (folder / "confirm.json").exists():
        for cond, v in json.loads((folder / "confirm.json").read_text())["verdicts"].items():
            out[("confirm", cond)] = v
    if (folder / "study.json").exists():
        for v in json.loads((folder / "study.json").read_text())["verdicts"]:
            out[("H3", f"Task {v['task']}")] = v["verdict"]
    return out


def improvements(folder: Path) -> dict[tuple[str, ...], float]:
    """Every P(reference better in a run) of stats.csv (folders written before it: none)."""
    return {
        tuple(r[c] for c in ("env", "condition", "metric", "baseline")): _num(r["prob_improvement"])
        for r in _rows(folder / "stats.csv")
        if r.get("prob_improvement")
    }


def tests_table(folders: dict[str, Path], metrics: Sequence[str] | None = None) -> list[str]:
    """Markdown: every post-hoc test (both tests) of the folders, one row each: its Holm p and
    verdict under the first setting, how the other settings differ (their p to 3 significant
    digits and verdict; "same" when every one agrees) and "**depends on the CPU**" where the
    verdicts differ."""
    per = {s: tests(f) for s, f in folders.items()}
    ref, *others = folders
    keys = sorted(set().union(*per.values()), key=lambda k: (k[1:], k[0]))
    if metrics is not None:
        keys = [k for k in keys if k[3] in metrics]
    lines = [
        f"| env | condition | metric | vs | test | Holm p (verdict), {ref} | "
        f"{', '.join(others) or 'other settings'} | CPU-dependent |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k in keys:
        cells = {s: per[s].get(k, (math.nan, "missing")) for s in folders}
        shown = {s: f"{p:.3g} ({v})" for s, (p, v) in cells.items()}
        differ = [f"{s}: {shown[s]}" for s in others if shown[s] != shown[ref]]
        depends = len({v for _, v in cells.values()}) > 1
        lines.append(
            f"| {k[1]} | {k[2]} | {k[3]} | {k[5]} | {k[0]} | {shown[ref]} | "
            f"{'; '.join(differ) or 'same'} | {'**depends on the CPU**' if depends else 'no'} |"
        )
    return lines


def rel_diff(a: float, b: float) -> float:
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def compare(ref: Path, other: Path) -> tuple[float, tuple[str, ...] | None, list[str], float]:
    """(largest relative difference of a mean, where, verdicts that changed, largest absolute
    difference of a probability of improvement)."""
    ma, mb = means(ref), means(other)
    worst, where = 0.0, None
    for key in ma.keys() & mb.keys():
        d = rel_diff(ma[key], mb[key])
        if d > worst:
            worst, where = d, key
    pa, pb = improvements(ref), improvements(other)
    poi = max((abs(pa[k] - pb[k]) for k in pa.keys() & pb.keys()), default=math.nan)
    va, vb = folder_verdicts(ref), folder_verdicts(other)
    changed = [f"{'/'.join(k)}: {va[k]} -> {vb.get(k)}" for k in sorted(va) if va[k] != vb.get(k)]
    return worst, where, changed, poi


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--settings", default=",".join(DEFAULT_SETTINGS), help="comma-separated")
    p.add_argument("--out", default="results/cross-kernel", help="parent of the result folders")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--tests-md", default="", help="also write every test (all metrics) here")
    p.add_argument(
        "--compare-only", action="store_true", help="compare the folders under --out, run nothing"
    )
    p.add_argument("--robot-runs", type=int, default=0, help="paper --env robot --runs (paper's)")
    p.add_argument("--highway-runs", type=int, default=0, help="paper --env highway --runs")
    p.add_argument("--confirm-runs", type=int, default=200, help="0: the full protocol (200)")
    p.add_argument("--study-users", type=int, default=4, help="0: the study's default (4)")
    p.add_argument(
        "--only", type=lambda s: s.split(","), default=["paper", "confirm", "study"],
        help="outputs to run: paper, confirm, study (all)",
    )  # fmt: skip
    args = p.parse_args(argv)
    settings = [s.strip() for s in args.settings.split(",") if s.strip()]
    for s in settings:
        setting_env(s)  # checks the syntax up front
    skipped = [s for s in settings if not runnable(s)]
    settings = [s for s in settings if runnable(s)]
    if skipped:
        print(f"skipped (this CPU has no AVX-512): {', '.join(skipped)}")
    cmds = commands(args)
    bench = [sys.executable, "-m", "strol_gym.benchmarks"]
    labels = {}
    for s in [] if args.compare_only else settings:
        env = {**os.environ, **setting_env(s)}
        for name, (argv_, _) in cmds.items():
            folder = Path(args.out) / s.replace(":", "-") / name.replace(" --env ", "-")
            t0 = time.perf_counter()
            subprocess.run([*bench, *argv_, "--out", str(folder)], env=env, check=True,
                           stdout=subprocess.DEVNULL)  # fmt: skip
            meta = json.loads((folder / "meta.json").read_text())
            labels[s] = kernel_label(meta["kernels"])
            print(f"ran {name} under {s} in {time.perf_counter() - t0:.0f} s", flush=True)
    print()
    for s in settings:
        for name in cmds:
            meta = Path(args.out) / s.replace(":", "-") / name.replace(" --env ", "-") / "meta.json"
            if s not in labels and meta.exists():
                labels[s] = kernel_label(json.loads(meta.read_text())["kernels"])
        print(f"{s}: {labels.get(s)}")
    ref = settings[0]
    print(f"\nagainst {ref}:")
    print(
        "| output | setting | largest relative difference of a mean (where) | largest change "
        "of a P(improvement) | verdicts changed (t and Wilcoxon) |"
    )
    print("|---|---|---|---|---|")
    for name, (_, reduced) in cmds.items():
        label = f"{name} (reduced: {reduced})" if reduced else name
        stem = name.replace(" --env ", "-")
        for s in settings[1:]:
            a = Path(args.out) / ref.replace(":", "-") / stem
            b = Path(args.out) / s.replace(":", "-") / stem
            worst, where, changed, poi = compare(a, b)
            at = f" ({'/'.join(where)})" if where else ""
            print(f"| {label} | {s} | {worst:.2g}{at} | {poi:.3g} | {len(changed) or 'none'} |")
            for c in changed:
                print(f"|  |  | changed: {c} | | |")
    for name in cmds:
        stem = name.replace(" --env ", "-")
        folders = {s: Path(args.out) / s.replace(":", "-") / stem for s in settings}
        if all((f / "stats.csv").exists() for f in folders.values()):
            print(f"\nevery post-hoc test of {name} on its primary metric, under each setting:")
            print("\n".join(tests_table(folders, primary_metrics(folders))))
            if args.tests_md:
                path = Path(args.tests_md).with_suffix(f".{stem}.md")
                write_text_atomic(path, "\n".join(tests_table(folders)) + "\n")
                print(f"every test of {name} (all metrics): {path}")
    return 0


def primary_metrics(folders: dict[str, Path]) -> list[str]:
    """The primary metric of each env in the folders' stats.csv (Robot regret, Highway error)."""
    from strol_gym.benchmarks.engine.conditions import env_preset

    envs = {r["env"] for f in folders.values() for r in _rows(f / "stats.csv")}
    out = []
    for env in sorted(envs):
        try:
            out.append(env_preset(env).primary_metric)
        except (KeyError, ValueError):
            out.append("error")
    return out


if __name__ == "__main__":
    sys.exit(main())
