"""import-study and the folder replay, on synthetic files in the authors' layout written here.

Nothing of the authors' data is in the repository: each test writes its own pickles (numpy
arrays inside lists and dicts, as theirs are), in their folder layout, from cup poses chosen
in our frame and mapped to their logged frame with the fitted transform.
"""

from __future__ import annotations

import csv
import os
import pickle

import numpy as np
import pytest
from cli_checks import cli_error

from strol_gym.benchmarks import cli
from strol_gym.benchmarks.sessions.authors_frame import fit_transform, frame_to_pose, logged_frame
from strol_gym.benchmarks.sessions.authors_rules import implied_theta0
from strol_gym.benchmarks.sessions.plain_pickle import PickleRefused, load_plain_pickle
from strol_gym.tasks.study import STUDY_TASKS
from strol_gym.wrappers.session_log import read_session

RNG_SEED = 32


def _home_cup(task: int) -> np.ndarray:
    """Our cup pose (6-D) at Task ``task``'s home, through the fitted transform."""
    fit = fit_transform()
    return frame_to_pose(logged_frame(STUDY_TASKS[task]().home_q) @ fit.transform)


def _session(task: int, rng: np.random.Generator, moves: list[np.ndarray], sizes: list[int]):
    """A session dict in the authors' layout: a short path from home, one correction per entry
    of ``sizes`` (poses logged), those with ≥ 2 poses moving the cup by the next of ``moves``."""
    fit = fit_transform()
    home = _home_cup(task)
    path = home + np.outer(np.linspace(0, 1, 40), [0.05, -0.05, -0.02, 0.0, 0.0, 0.0])
    corrections, m = [], 0
    for k, n in enumerate(sizes):
        start = path[10 * (k + 1) % 40]
        if n >= 2:
            poses = start + np.outer(np.linspace(0, 1, n), moves[m])
            m += 1
        else:
            poses = start[None, :].repeat(n, axis=0)
        corrections.append([row for row in fit.to_logged(poses)])  # a list of (6,) arrays
    d = STUDY_TASKS[task]().dim
    final = rng.uniform(-1, 1, d).astype(np.float32)
    return {
        "theta_learned": [[final] * len(sizes)],  # the final θ̂ once per correction (aliased)
        "theta_star": [STUDY_TASKS[task]().theta_star],
        "robot_traj": [[row for row in fit.to_logged(path)]],
        "corrections": [corrections],
        "traj_learned": [fit.to_logged(path[:20])],
        "traj_star": [fit.to_logged(path[:20])],
    }


def _write(root, user: str, task: int, alg: str, data) -> None:
    folder = root / user / f"task_{task}" / alg
    folder.mkdir(parents=True)
    with open(folder / "data.pkl", "wb") as f:
        pickle.dump(data, f)


@pytest.fixture(scope="module")
def tree(authors_tree):
    """user_1 and user_2, Tasks 1 and 2, every algorithm; a user_pilot folder to skip."""
    moves: dict = {}
    root = authors_tree(people=2, seed=RNG_SEED, tasks=(1, 2), moves=moves)
    _write(root, "user_pilot", 1, "b1", {"not": "a session"})
    return root, moves


def test_frame_transform_round_trip_and_fit():
    fit = fit_transform()
    cup = np.random.default_rng(RNG_SEED).uniform(
        [0.2, -0.6, 0.05, -1.3, -1.3, -np.pi], [0.8, 0.6, 0.7, 1.3, 1.3, np.pi], (200, 6)
    )
    back = fit.to_cup(fit.to_logged(cup))
    assert np.allclose(back[:, :3], cup[:, :3], atol=1e-12)
    assert np.allclose(np.angle(np.exp(1j * (back[:, 3:] - cup[:, 3:]))), 0, atol=1e-9)
    # one rigid offset explains both homes (the two differ by ~20 cm and 60°)
    assert max(fit.residual_mm.values()) < 0.5 and max(fit.residual_deg.values()) < 0.1
    assert max(fit.loo_mm.values()) < 0.5
    # and it is a shift of ~5 cm along the hand's axis and a quarter turn about it
    assert abs(fit.offset_mm[2] + 49.6) < 1.0 and np.hypot(*fit.offset_mm[:2]) < 1.0
    assert abs(fit.turn_deg + 90.0) < 0.2


def test_import_one_update_per_correction(tree, tmp_path, capsys):
    root, moves = tree
    out = tmp_path / "logs"
    assert cli.main(["import-study", str(root), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "wrote 12 session logs" in text and "residual" in text and "logged starts" in text
    logs = sorted(out.glob("*.jsonl"))
    assert len(logs) == 12 and not any("pilot" in p.name for p in logs)
    for path in logs:
        user, _, task, alg = path.stem.split("_")[1:]
        task = int(task)
        s = read_session(path)
        assert s.header["learner"] == {"b1": "one", "b2": "mof", "ours": "strol"}[alg]
        assert s.header["task"] == f"study-task{task}"
        assert "theta_hat per correction" in s.header["extra"]["unknown"]
        ep = s.episodes[0]
        # the empty and the one-pose corrections give no update; the two others one each
        assert len(ep.corrections) == 2
        want_dim = 3 if task == 1 else 6
        for c, mv in zip(ep.corrections, moves[(f"user_{user}", task, alg)], strict=True):
            assert c["u_h"].shape == (want_dim,)
            assert np.allclose(c["u_h"], mv[:want_dim], atol=1e-9)  # our frame, to the bit
            assert np.allclose(c["u_r"], 0) and c["theta_hat_after"] is None
            assert c["correction_time"] is None
        mean = np.mean(STUDY_TASKS[task]().prior_modes, axis=0)
        assert np.allclose(ep.theta_hat0, mean)
    first = logs[0].read_text().splitlines()[1]
    assert '"corrections_empty": 1' in first and '"corrections_one_pose": 1' in first


def test_import_authors_updates_and_implied_theta0(tree, tmp_path):
    root, moves = tree
    out = tmp_path / "logs"
    argv = ["import-study", str(root), "--out", str(out), "--authors-updates"]
    assert cli.main([*argv, "--theta0", "implied"]) == 0
    s = read_session(out / "user_2_task_2_b1.jsonl")
    ep = s.episodes[0]
    # 5 and 3 logged poses: 4 + 2 per-sample updates of 3·Δ, summing to 3 × each move
    assert len(ep.corrections) == 6
    total = sum(c["u_h"] for c in ep.corrections)
    assert np.allclose(total, 3 * sum(moves[("user_2", 2, "b1")]), atol=1e-9)
    raw = load_plain_pickle(root / "user_2" / "task_2" / "b1" / "data.pkl")
    corr = [np.asarray(c, dtype=float).reshape(-1, 6) for c in raw["corrections"][0]]
    final = np.asarray(raw["theta_learned"][0][-1], dtype=float)
    assert np.allclose(ep.theta_hat0, implied_theta0(final, corr, 2, "one"))
    # θ̂ per correction reconstructed: chained from θ̂0 to the logged final θ̂, said so
    hats = [ep.theta_hat0] + [np.asarray(c["theta_hat_after"]) for c in ep.corrections]
    steps = np.diff(np.array(hats), axis=0)
    assert np.allclose(hats[-1], final) and all(np.any(d != 0.0) for d in steps)
    assert s.header["extra"]["theta_hat"].startswith("reconstructed")
    assert "theta_hat0" not in s.header["extra"]["unknown"]
    # StROL's rule gives no implied θ̂0: the prior mean, marked as such, θ̂ unknown and why
    strol_log = read_session(out / "user_2_task_2_ours.jsonl")
    strol = strol_log.episodes[0]
    assert np.allclose(strol.theta_hat0, np.mean(STUDY_TASKS[2]().prior_modes, axis=0))
    assert all(c["theta_hat_after"] is None for c in strol.corrections)
    assert "ĝ" in strol_log.header["extra"]["theta_hat"]


def test_import_refuses_existing_logs(tree, tmp_path, capsys):
    root, _ = tree
    out = tmp_path / "logs"
    assert cli.main(["import-study", str(root), "--out", str(out)]) == 0
    capsys.readouterr()
    assert "never overwritten" in cli_error(["import-study", str(root), "--out", str(out)], capsys)


class _RunsCode:
    """What an attacker's pickle holds: loading it would call os.system."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def test_pickle_payload_refused(tmp_path, capsys):
    marker = tmp_path / "ran"
    root = tmp_path / "data"
    good = {k: [np.zeros(3)] for k in ("theta_star", "traj_learned", "traj_star")}
    bad = {**good, "theta_learned": [[]], "robot_traj": [[_RunsCode(marker)]], "corrections": [[]]}
    _write(root, "user_1", 1, "b1", bad)
    err = cli_error(["import-study", str(root), "--out", str(tmp_path / "out")], capsys)
    assert "data.pkl" in err and "refused: global" in err and ".system" in err
    assert not marker.exists() and not (tmp_path / "out").exists()


def test_pickle_reader_admits_arrays_only(tmp_path):
    path = tmp_path / "x.pkl"
    path.write_bytes(pickle.dumps({"a": [np.arange(6.0).reshape(2, 3), 1, 2.5], "b": {"c": []}}))
    got = load_plain_pickle(path)
    assert np.array_equal(got["a"][0], np.arange(6.0).reshape(2, 3)) and got["b"] == {"c": []}
    for bad in (np.array([object()]), np.zeros(2, dtype=[("f", "f8")]), {1.5: 2}, {"s": {1, 2}}):
        path.write_bytes(pickle.dumps(bad))
        with pytest.raises(PickleRefused, match=r"x\.pkl"):
            load_plain_pickle(path)


class _HugeArray:
    """An ndarray's own pickle recipe with a shape of 10¹² elements and 24 bytes of data."""

    def __reduce__(self):
        fn, args, state = np.zeros(3).__reduce__()
        return fn, args, (state[0], (10**12,), *state[2:])


def test_array_sizes_checked_before_allocating(tmp_path):
    path = tmp_path / "huge.pkl"
    path.write_bytes(pickle.dumps([_HugeArray()]))
    with pytest.raises(PickleRefused, match=r"huge\.pkl.*elements"):
        load_plain_pickle(path)
    path.write_bytes(b"\x80\x04" + b"\x00" * 10)
    with pytest.raises(PickleRefused, match=r"huge\.pkl"):
        load_plain_pickle(path, max_bytes=5)


def test_replay_folder(tree, tmp_path, capsys):
    root, _ = tree
    logs = tmp_path / "logs"
    assert cli.main(["import-study", str(root), "--out", str(logs)]) == 0
    out = tmp_path / "replay"
    argv = ["replay", str(logs), "--learners", "gradient,one,strol,registry_pieces:HalfGradient"]
    assert cli.main([*argv, "--plugin", "registry_pieces", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "study1_strol.safetensors (StROL-Study-v0-task1)" in text and "RM-ANOVA" in text
    assert "(θ̂0: no update)" in text
    with open(out / "replay_sessions.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 6 * 4  # Tasks × sessions × learners, paired by session
    assert all(np.isfinite(float(r[m])) for r in rows for m in ("error", "cos_error", "regret"))
    grad = {r["session"]: float(r["error"]) for r in rows if r["learner"] == "gradient"}
    half = {r["session"]: float(r["error"]) for r in rows if "HalfGradient" in r["learner"]}
    assert grad.keys() == half.keys() and grad != half
    assert (out / "replay.png").stat().st_size > 0
    with open(out / "replay_stats.csv", encoding="utf-8") as f:
        stats = list(csv.DictReader(f))
    assert {r["test"] for r in stats} == {"rm-anova", "paired t"}
    # v1's Tasks have no strol-unrolled ĝ: left out, with a note, not an error
    argv = ["replay", str(logs), "--learners", "gradient,strol,strol-unrolled", "--no-plots"]
    assert cli.main([*argv, "--task-version", "1", "--out", str(tmp_path / "v1")]) == 0
    text = capsys.readouterr().out
    assert "strol-unrolled left out: no pretrained" in text
    assert "study1-v1_strol.safetensors (StROL-Study-v1-task1)" in text
    # bad input: a reference that is not replayed, a log that is not one
    bad = ["replay", str(logs), "--learners", "gradient,one", "--out", str(tmp_path / "bad")]
    assert "--reference 'strol' must be one of" in cli_error(bad, capsys)
    (logs / "junk.jsonl").write_text('{"type": "header"}\n')
    assert "junk.jsonl:1" in cli_error([*bad, "--reference", "one"], capsys)


def test_implied_theta0_by_hand():
    """One straight push down by 1 cm per logged step: the authors' One update is +3 cm on the
    table weight (|z| − |z − 0.03|), their gradient update also moves the plate weight."""
    start = np.array([0.4, 0.3, 0.5, 0.0, 0.0, 0.0])
    poses = np.array([start, start - [0, 0, 0.01, 0, 0, 0]])
    final = np.array([-1.0, 0.5, 0.8])
    got = implied_theta0(final, [poses, poses[:1], poses[:0]], 1, "one")
    assert np.allclose(got, final - [0.0, 0.0, 0.03], atol=1e-12)
    plate = STUDY_TASKS[1]().plate
    g_plate = np.linalg.norm(start[:3] - plate) - np.linalg.norm(start[:3] - [0, 0, 0.03] - plate)
    got = implied_theta0(final, [poses], 1, "gradient")
    assert np.allclose(got, final - [0.0, g_plate, 0.03], atol=1e-12)


def test_study_card_and_implied_check(tree, tmp_path, capsys):
    from lab.study import implied_check
    from strol_gym.benchmarks.sessions import study_card

    root, moves = tree
    logs = tmp_path / "logs"
    assert cli.main(["import-study", str(root), "--out", str(logs)]) == 0
    assert study_card.main([str(logs), "--out", str(tmp_path / "card")]) == 0
    card = (tmp_path / "card" / "card.md").read_text()
    assert "| corrections logged | 24 | 24 |" in card  # 6 sessions × 4 corrections per Task
    assert "| of which empty / one pose | 6 / 6 | 6 / 6 |" in card
    for task, col in ((1, 2), (2, 3)):
        cm = [100 * np.linalg.norm(m[:3]) for k, mv in moves.items() if k[1] == task for m in mv]
        row = next(r for r in card.splitlines() if r.startswith("| displacement"))
        assert float(row.split("|")[col]) == pytest.approx(np.mean(cm), abs=0.006)
    assert (tmp_path / "card" / "study_data_card.png").stat().st_size > 0
    capsys.readouterr()
    assert implied_check.main([str(root)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(implied_check.CHECKS) and all("/4" in ln for ln in lines)
