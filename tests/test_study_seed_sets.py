"""The seed-set check of the study's verdicts: how far a Task's verdict sits from flipping."""

from __future__ import annotations

import pytest

from lab.study.study_seed_sets import complete_users, decisive_margin


class _Tests:
    """Stands in for an Analysis: the four H3 tests of one Task, in H3_METRICS × H3_BASELINES
    order (regret vs One, vs MOF; correction time vs One, vs MOF)."""

    def __init__(self, rows):
        self.rows = iter(rows)

    def test(self, env, cond, base, metric):
        p, diff = next(self.rows)
        return {"p_holm": p, "mean_diff": diff, "significant": p < 0.05}


def test_a_supported_task_flips_when_its_largest_p_passes_alpha():
    a = _Tests([(0.01, -1.0), (0.04, -2.0), (0.001, -3.0), (0.02, -1.0)])
    margin, near = decisive_margin(a, "study2", "u")
    assert margin == pytest.approx(0.01) and near == pytest.approx(0.01)


def test_an_unsupported_task_flips_only_when_every_failing_test_passes():
    a = _Tests([(0.30, -1.0), (0.07, -2.0), (0.001, -3.0), (0.02, -1.0)])
    margin, near = decisive_margin(a, "study1", "u")
    assert margin == pytest.approx(0.25) and near == pytest.approx(0.02)
    # StROL significantly higher: more users would not turn it into support.
    a = _Tests([(0.001, +1.0), (0.01, -2.0), (0.001, -3.0), (0.02, -1.0)])
    assert decisive_margin(a, "study1", "u")[0] == 1.0


def test_complete_users_counts_users_with_every_run():
    full = [{"seed": s} for s in (5, 6) for _ in range(15)]  # 3 Tasks × 5 learners each
    assert complete_users([*full, {"seed": 7}], 5) == 2
    assert complete_users(full, 6) == 1 and complete_users(full, 4) == 0


def test_from_study_refuses_a_folder_that_is_not_a_study(tmp_path, capsys):
    """--from-study reads a results folder or exits 2 with one line naming the option."""
    from lab.study.study_seed_sets import main

    with pytest.raises(SystemExit) as e:
        main(["--from-study", str(tmp_path / "none")])
    assert e.value.code == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error:" in ln]
    assert len(err) == 1 and "--from-study" in err[0]
