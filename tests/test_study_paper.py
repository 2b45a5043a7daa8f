"""The authors' ĝ read from a checkout's layout, and the paper's StROL on imported sessions.

Nothing of the authors' is in the repository: each test writes its own tiny ĝ files in their
layout (``g_data/model_t1``, ``model_t2``: torch state dicts of their MLP's shapes, random
weights drawn here) and its own session pickles (the ``authors_tree`` fixture, ``conftest.py``).
"""

from __future__ import annotations

import csv
import itertools
import json
import os
import pickle

import numpy as np
import pytest
import torch
from cli_checks import cli_error

from strol_gym.benchmarks import cli
from strol_gym.benchmarks.sessions.authors_ghat import (
    PAPER_LAMBDA,
    layer_shapes,
    load_authors_ghat,
    state_keys,
)
from strol_gym.benchmarks.sessions.authors_rules import authors_task, sample_updates
from strol_gym.benchmarks.sessions.import_study import read_sessions
from strol_gym.benchmarks.sessions.replay import replay_session
from strol_gym.wrappers.session_log import read_session

SEED = 48


def _state(number: int, gen: torch.Generator, scale: float = 0.05) -> dict[str, torch.Tensor]:
    """A state dict of their MLP's keys and shapes, random weights."""
    shapes = [s for pair in layer_shapes(number) for s in pair]
    return {
        k: scale * torch.randn(s, generator=gen)
        for k, s in zip(state_keys(number), shapes, strict=True)
    }


@pytest.fixture(scope="module")
def gdir(tmp_path_factory):
    """A ``g_data`` folder in the authors' layout, written here."""
    root = tmp_path_factory.mktemp("checkout") / "g_data"
    root.mkdir()
    gen = torch.Generator().manual_seed(SEED)
    for number, name in ((1, "model_t1"), (2, "model_t2")):
        torch.save(_state(number, gen), root / name)
    return root


def _torch_mlp(number: int, state: dict[str, torch.Tensor]) -> torch.nn.Module:
    """Their architecture as torch layers (sizes from ``layer_shapes``), to check ours against."""
    layers: list[torch.nn.Module] = []
    for (out, inp), _ in layer_shapes(number):
        layers += [torch.nn.Linear(inp, out), torch.nn.ReLU()]
    layers[-1] = torch.nn.Tanh()
    net = torch.nn.Sequential(*layers)
    net.load_state_dict({k.removeprefix("learner."): v for k, v in state.items()})
    return net.double()


def test_forward_matches_torch_and_names_file(gdir):
    gen = torch.Generator().manual_seed(SEED)
    for number in (1, 2):
        state = _state(number, gen)  # the same draws the fixture saved
        g = load_authors_ghat(gdir, number)
        assert g.path.name == ("model_t1" if number == 1 else "model_t2")
        assert len(g.sha256) == 64 and g.describe()["lambda"] == PAPER_LAMBDA
        s = 3 if number == 1 else 6
        x = np.random.default_rng(SEED).normal(size=(7, s))
        u = np.random.default_rng(SEED + 1).normal(size=(7, s))
        want = _torch_mlp(number, state)(torch.from_numpy(np.hstack([x, u]))).detach().numpy()
        assert np.allclose(g(x, u), want, atol=1e-6)
        assert np.all(np.abs(g(x, u)) < 1.0) and np.any(np.abs(g(x, u)) > 1e-3)
    assert load_authors_ghat(gdir, 3).path.name == "model_t2"


def test_wrong_shape_missing_and_payload_refused(tmp_path):
    gen = torch.Generator().manual_seed(SEED)
    bad = tmp_path / "g_data"
    bad.mkdir()
    torch.save(_state(1, gen), bad / "model_t1")
    wrong = _state(2, gen)
    wrong["learner.4.weight"] = torch.zeros(100, 256)
    torch.save(wrong, bad / "model_t2")
    want = r"learner\.4\.weight has shape \(100, 256\).*\(128, 256\)"
    with pytest.raises(ValueError, match=want):
        load_authors_ghat(bad, 2)
    # a pickle whose load would make a folder: refused, and the folder is never made
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (os.mkdir, (str(marker),))

    (bad / "model_t2").write_bytes(pickle.dumps({"learner.0.weight": Payload()}))
    with pytest.raises(ValueError, match=r"--authors-ghat.*model_t2: refused, not a plain state"):
        load_authors_ghat(bad, 2)
    assert not marker.exists()
    (bad / "model_t2").unlink()
    os.mkfifo(bad / "model_t2")  # a reader would wait on it for ever: refused unopened
    with pytest.raises(ValueError, match=r"model_t2 is a FIFO.*not a regular file"):
        load_authors_ghat(bad, 2)
    (bad / "model_t2").unlink()
    with pytest.raises(ValueError, match=r"--authors-ghat .*no model_t2"):
        load_authors_ghat(bad, 1)
    with pytest.raises(ValueError, match=r"--authors-ghat .*not a folder"):
        load_authors_ghat(tmp_path / "nowhere", 1)


@pytest.fixture(scope="module")
def tree(authors_tree):
    """user_1 and user_2, Tasks 1 and 2, every algorithm."""
    return authors_tree(people=2, seed=SEED, tasks=(1, 2))


@pytest.fixture(scope="module")
def logs(tree, gdir, tmp_path_factory):
    """The tree imported with the implied θ̂0 and the ĝ written here."""
    out = tmp_path_factory.mktemp("paper_logs") / "logs"
    argv = ["import-study", str(tree), "--out", str(out), "--theta0", "implied"]
    assert cli.main([*argv, "--authors-ghat", str(gdir)]) == 0
    return out


def test_import_reconstructs_strol_sessions(tree, gdir, tmp_path, capsys):
    out = tmp_path / "logs"
    argv = ["import-study", str(tree), "--out", str(out), "--theta0", "implied"]
    assert cli.main([*argv, "--authors-ghat", str(gdir)]) == 0
    text = capsys.readouterr().out
    lines = [ln for ln in text.splitlines() if ln.startswith("implied θ̂0 inside [−1, 1]^d: ")]
    assert [ln.rsplit(":", 1)[1].split()[0] for ln in lines] == ["One", "MOF", "StROL"]
    assert all(ln.endswith(" of 4") for ln in lines)
    raws = {(r.task, r.alg): r for r in read_sessions(tree) if r.user == 1}
    for task in (1, 2):
        log = read_session(out / f"user_1_task_{task}_ours.jsonl")
        ghat = log.header["extra"]["authors_ghat"]
        assert sorted(ghat) == ["file", "lambda", "sha256"] and ghat["lambda"] == 0.25
        assert log.header["extra"]["theta_hat"].startswith("reconstructed")
        ep, raw = log.episodes[0], raws[(task, "ours")]
        # θ̂0 worked back by hand: final − Σ (g + 0.25 ĝ) over every logged pair, their φ
        at, g = authors_task(task), load_authors_ghat(gdir, task)
        total = np.zeros(at.dim)
        for poses in raw.corrections:
            if len(poses) >= 2:
                x, u = sample_updates(poses, task)
                total += (at.g(x, u, np.zeros_like(u)) + 0.25 * g(x, u)).sum(axis=0)
        assert np.allclose(ep.theta_hat0, raw.theta_final - total, atol=1e-9)
        cs = ep.corrections
        assert np.allclose(cs[0]["theta_hat_before"], ep.theta_hat0)
        assert np.allclose(cs[-1]["theta_hat_after"], raw.theta_final, atol=1e-9)
        for a, b in itertools.pairwise(cs):
            assert np.array_equal(a["theta_hat_after"], b["theta_hat_before"])
        used = [p for p in raw.corrections if len(p) >= 2]
        for c, poses in zip(cs, used, strict=True):
            assert np.array_equal(c["authors_poses"], poses)  # their logged frame, as logged
    # without the flag a StROL session's θ̂ stays unknown, the message names the flag
    out2 = tmp_path / "logs2"
    assert cli.main([*argv[:3], str(out2), *argv[4:]]) == 0
    assert "StROL" not in capsys.readouterr().out
    log = read_session(out2 / "user_1_task_2_ours.jsonl")
    assert "--authors-ghat" in log.header["extra"]["theta_hat"]
    assert all(c["theta_hat_after"] is None for c in log.episodes[0].corrections)


def test_import_refuses_bad_ghat_before_writing(tree, tmp_path, capsys):
    out = tmp_path / "never"
    msg = cli_error(
        ["import-study", str(tree), "--out", str(out), "--authors-ghat", str(tmp_path)], capsys
    )
    assert "--authors-ghat" in msg and "no model_t" in msg
    assert not out.exists()


def test_replay_both_strols(tree, gdir, logs, tmp_path, capsys):
    out = tmp_path / "replay"
    argv = ["replay", str(logs), "--authors-ghat", str(gdir), "--no-plots", "--out", str(out)]
    assert cli.main(argv) == 0  # default learners: the suite's four and strol-paper
    text = capsys.readouterr().out
    rows = [ln.split(" | ")[0].lstrip("| ") for ln in text.splitlines() if ln.startswith("| ")]
    assert rows.count("StROL") == 2 and rows.count("StROL (paper's ĝ, authors' φ)") == 2
    sha = load_authors_ghat(gdir, 1).sha256[:12]
    assert f"authors' model_t1 ({sha})" in text and "regret n/a" in text
    with open(out / "replay_sessions.csv", encoding="utf-8") as f:
        per = list(csv.DictReader(f))
    assert len(per) == 2 * 6 * 5
    for r in per:
        paper = r["learner"] == "strol-paper"
        assert np.isfinite(float(r["cos_error"])) and paper == np.isnan(float(r["regret"]))
    with open(out / "replay_stats.csv", encoding="utf-8") as f:
        stats = list(csv.DictReader(f))
    tested = {(r["metric"], r["baseline"]) for r in stats if r["test"] == "paired t"}
    assert ("cos_error", "strol-paper") in tested and ("regret", "strol-paper") not in tested
    # each session's own rule, replayed in the authors' space, ends at the logged final θ̂
    raws = {(r.user, r.task, r.alg): r for r in read_sessions(tree)}
    for user, task, alg in [(1, 1, "b2"), (2, 2, "b2"), (1, 2, "ours"), (2, 1, "ours")]:
        name = "gradient@authors" if alg == "b2" else "strol-paper"
        session = read_session(logs / f"user_{user}_task_{task}_{alg}.jsonl")
        curve = replay_session(session, [name], authors_ghat=str(gdir))[name][0]
        assert np.allclose(curve[-1], raws[(user, task, alg)].theta_final)


def test_replay_paper_needs_flag_and_poses(gdir, logs, tmp_path, capsys):
    argv = ["replay", str(logs), "--learners", "strol,strol-paper", "--out", str(tmp_path / "r")]
    assert "--authors-ghat GDIR" in cli_error(argv, capsys)
    assert "--authors-ghat" in cli_error([*argv, "--authors-ghat", str(tmp_path)], capsys)
    assert not (tmp_path / "r").exists()
    # a log without the authors' poses cannot feed a learner in their space
    bare = tmp_path / "bare.jsonl"
    lines = []
    for line in (logs / "user_1_task_2_b1.jsonl").read_text().splitlines():
        rec = json.loads(line)
        rec.pop("authors_poses", None)
        lines.append(json.dumps(rec))
    bare.write_text("\n".join(lines) + "\n")
    one = ["replay", str(bare), "--learners", "one@authors", "--no-plots"]
    assert "no 'authors_poses'" in cli_error([*one, "--out", str(tmp_path / "b")], capsys)


def test_paper_strol_drives_study_v2_stepping_per_pair_of_poses(gdir, monkeypatch):
    """lab/study/paper_strol.py: without STROL_AUTHORS_GHAT it says which variable to set; with
    it, one v2 push of length L is L / 1.26 cm pair updates of the paper's rule along the push
    (in the authors' frame), from the learner's own θ̂, and θ̂ moves."""
    from lab.study import paper_strol
    from strol_gym.benchmarks.sessions.authors_frame import fit_transform
    from strol_gym.benchmarks.sessions.authors_rules import rule_learner
    from strol_gym.tasks.study import STUDY_TASKS_V2

    task = STUDY_TASKS_V2[1]()
    monkeypatch.delenv(paper_strol.ENV, raising=False)
    with pytest.raises(ValueError, match=paper_strol.ENV):
        paper_strol.PaperStrolV2(task)
    monkeypatch.setenv(paper_strol.ENV, str(gdir))
    learner = paper_strol.PaperStrolV2(task)
    rng = np.random.default_rng(SEED)
    theta0 = rng.uniform(-1.0, 1.0, task.dim)
    learner.reset(theta0)
    x, u = np.asarray(task.start, dtype=np.float64), np.array([0.06, -0.02, -0.03])
    after = learner.update(x, u, np.zeros(3))
    n = round(float(np.linalg.norm(u)) / paper_strol.POSE_STEP)  # 0.07 m: 6 pairs
    cup = np.zeros((n + 1, 6))
    cup[:, :3] = x + np.outer(np.arange(n + 1) / n, u)
    poses = fit_transform().to_logged(cup)[:, :3]
    rule = rule_learner("strol-paper", 1, gdir)
    rule.reset(theta0)
    for a, b in itertools.pairwise(poses):
        rule.update(a, 3.0 * (b - a), np.zeros(3))
    assert n == 6 and not np.allclose(after, theta0)
    np.testing.assert_allclose(after, rule.theta, rtol=0, atol=1e-12)
