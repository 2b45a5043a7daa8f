"""docs/getting-started.md: its Python blocks run top to bottom as one session, and its
``strol-bench`` lines run through the CLI's entry point, in a temporary folder."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from strol_gym.benchmarks.cli import main

PAGE = Path(__file__).resolve().parents[1] / "docs" / "getting-started.md"


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", PAGE.read_text(), flags=re.S)


def test_python_blocks_run(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    blocks = _blocks("python")
    assert len(blocks) == 3, "the page lost an example (first env, learner, benchmark)"
    namespace: dict = {"__name__": "getting_started"}
    for i, block in enumerate(blocks):
        exec(compile(block, f"{PAGE}:block{i}", "exec"), namespace)
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "['correction', 'phi', 'state', 'theta_hat']"
    learned = [line for line in out if line.startswith(("gradient:", "strol:"))]
    assert [line.split(":")[0] for line in learned] == ["gradient", "strol"]
    errors = [float(line.split()[2].rstrip(",")) for line in learned]
    assert all(e >= 0.0 for e in errors)
    summary = [line.split() for line in out if line.startswith(("gradient training", "strol "))]
    assert [s[0] for s in summary] == ["gradient", "strol"]
    assert all(float(s[2]) >= 0.0 for s in summary)
    assert (tmp_path / "first-run" / "summary.md").is_file()


@pytest.mark.parametrize(
    "line",
    [
        line.strip()
        for block in _blocks("bash")
        for line in block.splitlines()
        if line.strip().startswith("strol-bench ")
    ],
)
def test_command_lines_run(line, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(shlex.split(line)[1:]) == 0
    out = capsys.readouterr().out
    if " run " in f" {line} ":
        assert (tmp_path / "first-run-cli" / "summary.csv").is_file()
        assert "StROL" in out
    else:
        assert "StROL-Robot-v0" in out


def test_home_page_quickstart_runs(capsys):
    home = PAGE.parent / "index.md"
    first = re.findall(r"```python\n(.*?)```", home.read_text(), flags=re.S)[0]
    assert "OnlineLearningWrapper" in first, "the home page no longer leads with the quickstart"
    exec(compile(first, f"{home}:quickstart", "exec"), {"__name__": "quickstart"})
    error, regret = (float(v) for v in capsys.readouterr().out.split())
    assert error >= 0.0 and regret >= -1e-9


# ------------------------------------------------------------------ the tutorials
# Every command a tutorial shows runs here, on a small config of the same command: fewer runs,
# steps and samples, one worker, no plots, into the test's folder. The arguments that pick what
# runs (env, learners, Task, kind, plugin) are the page's own.
DOCS = PAGE.parent
SMALL = {"--runs": "4", "--steps": "3", "--batch": "8", "--heldout": "16", "--jobs": "1"}
VERDICT = re.compile(r"^H[12] robot/[a-z-]+ \(regret\): (holds|FAILS) — ")


def _page_blocks(page: Path, lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", page.read_text(encoding="utf-8"), flags=re.S)


def _commands(page: Path) -> list[list[str]]:
    """The page's command lines as ``strol-bench`` arguments (``python -m
    strol_gym.benchmarks.train ARGS`` is ``strol-bench train ARGS``), continuation lines
    joined, comments dropped."""
    out = []
    for block in _page_blocks(page, "bash"):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words[:1] and words[0].endswith("strol-bench"):
                out.append(words[1:])
            elif "strol_gym.benchmarks.train" in words:
                out.append(["train", *words[words.index("strol_gym.benchmarks.train") + 1 :]])
    return out


def _small(argv: list[str], out: Path) -> list[str]:
    """The same command on a small config, writing into ``out``."""
    args = list(argv)
    for option, value in SMALL.items():
        if option in args:
            args[args.index(option) + 1] = value
        elif option in ("--runs", "--jobs") and args[0] in ("paper", "run"):
            args += [option, value]
        elif option in ("--steps", "--batch", "--heldout") and args[0] == "train":
            args += [option, value]
    if "--out" in args:
        args[args.index("--out") + 1] = str(out)
    else:
        args += ["--out", str(out)]
    quiet = {"paper": ("--no-plots", "--quiet"), "run": ("--no-plots", "--quiet")}
    return args + [a for a in quiet.get(args[0], ("--quiet",)) if a not in args]


def test_first_comparison_commands_run_and_print_the_verdicts_the_page_explains(
    tmp_path, monkeypatch, capsys
):
    page = DOCS / "tutorials" / "first-comparison.md"
    commands = _commands(page)
    assert [c[:2] for c in commands] == [["paper", "--env"]] * 2
    quoted = [
        line
        for block in _page_blocks(page, "text")
        for line in block.splitlines()
        if line.startswith("H")
    ]
    assert len(quoted) == 4 and all(VERDICT.match(line) for line in quoted)
    assert any("FAILS" in line for line in quoted)  # the page explains a failing verdict
    monkeypatch.chdir(tmp_path)
    for i, command in enumerate(commands):
        assert main(_small(command, tmp_path / f"out{i}")) == 0
        printed = [line for line in capsys.readouterr().out.splitlines() if line[:1] == "H"]
        # the same four verdict lines, in the page's order and format
        assert [line.split(":")[0] for line in printed] == [q.split(":")[0] for q in quoted]
        assert all(VERDICT.match(line) for line in printed)


def test_own_learner_tutorial_runs(tmp_path, monkeypatch, capsys):
    from strol_gym.learners.registry import list_learners, unregister_learner

    page = DOCS / "tutorials" / "own-learner.md"
    blocks = _page_blocks(page, "python")
    assert blocks[0].startswith("# my_rules.py")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_rules.py").write_text(blocks[0])
    namespace: dict = {"__name__": "own_learner"}
    try:
        for i, block in enumerate(blocks):
            exec(compile(block, f"{page}:block{i}", "exec"), namespace)
        out = capsys.readouterr().out.splitlines()
        assert "half-gradient passes check_learner" in out
        errors = {line.split(":")[0]: float(line.split()[-1]) for line in out if "error" in line}
        assert set(errors) == {"gradient", "half-gradient", "strol"}
        assert all(e >= 0.0 for e in errors.values())
        # a fresh shell has not registered it: the command's --plugin does
        unregister_learner("half-gradient")
        (command,) = _commands(page)
        assert main(_small(command, tmp_path / "bench")) == 0
        assert "Half-gradient" in (tmp_path / "bench" / "summary.md").read_text()
    finally:
        if "half-gradient" in list_learners():
            unregister_learner("half-gradient")


def test_training_tutorial_commands_run(tmp_path, monkeypatch):
    page = DOCS / "training.md"
    commands = _commands(page)
    assert commands and all(c[0] == "train" for c in commands)
    monkeypatch.chdir(tmp_path)
    for i, command in enumerate(commands):
        out = tmp_path / f"w{i}.safetensors"
        assert main(_small(command, out)) == 0
        assert out.is_file()
    (block,) = _page_blocks(page, "python")
    small = re.sub(r"steps=\d+", "steps=3", re.sub(r"batch=\d+", "batch=8", block))
    exec(compile(small, f"{page}:api", "exec"), {"__name__": "training"})
    assert (tmp_path / "mine.safetensors").is_file()
