"""docs/extending.md, "Your own Task end to end", as a user would follow it: the Task in a file
outside the package, the error that tells how to train ĝ, training by the command it prints, and
the benchmark with that checkpoint by the page's own command. Only the sizes are made tiny."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

PAGE = Path(__file__).resolve().parents[1] / "docs" / "extending.md"
TINY = {
    "train": ["--steps", "4", "--batch", "8", "--heldout", "50", "--quiet"],
    "run": ["--runs", "2", "--corrections", "2", "--jobs", "1", "--quiet", "--no-plots"],
}


def _strol_bench() -> list[str]:
    script = Path(sys.executable).with_name("strol-bench")
    return [str(script)] if script.exists() else [sys.executable, "-m", "strol_gym.benchmarks"]


def _call(argv: list[str], cwd: Path, **env: str) -> subprocess.CompletedProcess:
    """``strol-bench ARGV`` (the first word of a documented command) in ``cwd``."""
    assert argv[0] == "strol-bench", argv
    return subprocess.run(
        _strol_bench() + argv[1:],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, **env},
    )


def _doc_commands() -> tuple[str, list[list[str]]]:
    text = PAGE.read_text()
    module = re.search(r"```py\n# my_task\.py\n(.*?)```", text, flags=re.S)
    assert module, "docs/extending.md lost the my_task.py example"
    block = re.search(r"```bash\n(strol-bench train --plugin my_task\.py.*?)```", text, re.S)
    assert block, "docs/extending.md lost the train -> run example"
    lines = block.group(1).replace("\\\n", " ").strip().splitlines()
    return module.group(1), [shlex.split(line) for line in lines]


def test_own_task_train_then_benchmark_strol_with_its_checkpoint(tmp_path):
    source, (train, run) = _doc_commands()
    (tmp_path / "my_task.py").write_text(source)
    assert train[:2] == ["strol-bench", "train"] and run[:2] == ["strol-bench", "run"]

    # StROL without a checkpoint for this Task: the error prints how to get and pass one.
    k = run.index("--learner-kwargs")
    no_checkpoint = run[:k] + run[k + 2 :] + TINY["run"]
    refused = _call(no_checkpoint, tmp_path)
    assert refused.returncode == 2, refused.stderr[-2000:]
    suggested = re.findall(r"`(strol-bench train [^`]*)`", refused.stderr)
    assert len(suggested) == 1, refused.stderr
    kwargs = re.search(r"`--learner-kwargs ([^`]*)`", refused.stderr)
    assert kwargs and shlex.split(kwargs.group(1)) == [run[k + 1]], refused.stderr

    # The printed command trains (tiny sizes appended); the page's command is the same one.
    printed = shlex.split(suggested[0])
    plugin = printed.index("--plugin") + 1
    assert Path(printed[plugin]) == tmp_path / "my_task.py"
    assert printed[:plugin] + printed[plugin + 1 :] == train[:plugin] + train[plugin + 1 :]
    trained = _call(printed + TINY["train"], tmp_path)
    assert trained.returncode == 0, trained.stderr[-2000:]
    assert (tmp_path / "near-cup_strol.safetensors").is_file()

    done = _call(run + TINY["run"] + ["--out", "results"], tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    summary = (tmp_path / "results" / "summary.md").read_text()
    assert "StROL" in summary and "noisy-biased" in summary and "training" in summary


def test_installed_plugin_is_found_without_the_option(tmp_path):
    """A package declaring a ``strol_gym.plugins`` entry point registers its pieces at start."""
    site = tmp_path / "site"
    (site / "my_installed_task-0.1.dist-info").mkdir(parents=True)
    (site / "my_installed_task-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: my-installed-task\nVersion: 0.1\n"
    )
    (site / "my_installed_task-0.1.dist-info" / "entry_points.txt").write_text(
        "[strol_gym.plugins]\nmine = my_installed_task\n"
    )
    source, _ = _doc_commands()
    (site / "my_installed_task.py").write_text(source.replace('"near-cup"', '"installed-cup"'))
    listed = _call(["strol-bench", "list"], tmp_path, PYTHONPATH=str(site))
    assert listed.returncode == 0, listed.stderr[-2000:]
    assert "installed-cup (yours)" in listed.stdout
    alone = _call(["strol-bench", "list"], tmp_path)
    assert "installed-cup" not in alone.stdout
