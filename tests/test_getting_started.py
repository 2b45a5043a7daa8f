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
