"""Inputs that grow without bound are capped by the caps table: the corrections ``fit-human``
reads (its memory grows with them; ``--allow-large`` lifts the cap) and ``robustness
--sigmas``; ``fit-human --compare`` that names no model is refused."""

from __future__ import annotations

import pytest
from cli_checks import cli_error
from test_fit_human import _log

from strol_gym import limits
from strol_gym.benchmarks.sessions.fit_human import load_corrections


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    path = tmp_path_factory.mktemp("sizes") / "s.jsonl"
    _log(path)  # 4 episodes of 5 corrections
    return path


def test_fit_human_reads_at_most_the_capped_corrections(log, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(limits.CAPS, "fit_corrections", 12)
    with pytest.raises(ValueError, match=r"more than 12 corrections .*--allow-large lifts it"):
        load_corrections([str(log)])
    argv = ["fit-human", str(log), "--human", "nominal", "--out", str(tmp_path / "o")]
    argv += ["--bootstrap", "0", "--folds", "2", "--no-plots"]
    assert "the cap fit_corrections" in cli_error(argv, capsys)
    with limits.lifted():  # what --allow-large does (check_size_caps lifts the caps)
        assert len(load_corrections([str(log)]).person) == 20


def test_fit_human_compare_naming_no_model_is_refused(log, tmp_path, capsys):
    argv = ["fit-human", str(log), "--human", "nominal", "--compare", ",", "--out", str(tmp_path)]
    assert "--compare must name models" in cli_error(argv, capsys)


def test_robustness_sigmas_are_capped(tmp_path, capsys):
    many = ",".join(f"{0.001 * i:.3f}" for i in range(limits.CAPS["sigmas"] + 1))
    argv = ["robustness", "--env", "robot", "--sigmas", many, "--out", str(tmp_path / "o")]
    assert "--sigmas must be at most 100" in cli_error(argv, capsys)


def test_allow_large_lifts_the_caps_for_its_command_only(log, tmp_path, capsys):
    """A second command in the same process (a notebook, a test) is capped again."""
    argv = ["fit-human", str(log), "--human", "nominal", "--compare", ",", "--allow-large"]
    assert "--compare must name models" in cli_error([*argv, "--out", str(tmp_path)], capsys)
    assert not limits.lifted_now()
