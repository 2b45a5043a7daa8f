"""The paper's remaining experiments: the changing human, basin_map, and the
changing / lambda / basin / confirm presets from the CLI (tiny runs on diagnostic seeds; the
confirmatory protocol's seeds 3_000_000+ are never used here)."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.analysis import basin_map
from strol_gym.benchmarks import cli
from strol_gym.benchmarks.engine.kernels import float_kernels
from strol_gym.benchmarks.experiments import confirm
from strol_gym.humans import ChangingHuman, human_factory
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.robot import RobotTask

SEED = 1000  # the diagnostics seed range


# ---------------------------------------------------------------------- the changing human
def test_changing_human_switches_after_k_corrections():
    task = RobotTask()
    star = np.array([0.8, -0.8])
    h = ChangingHuman(task, star, np.random.default_rng(0), switch_after=2)
    x, u_r, th = task.start, np.zeros(3), np.zeros(2)
    seen = []
    for _ in range(5):
        h.act(x, u_r, th)
        seen.append(h.theta_star.copy())
    np.testing.assert_array_equal(seen[:2], [star, star])
    np.testing.assert_array_equal(seen[2:], [-star] * 3)
    assert human_factory("changing") is ChangingHuman


def test_changing_human_env_reports_final_preference():
    env = gym.make(
        "StROL-Robot-v0",
        person={"name": "changing", "kwargs": {"switch_after": 1}},
        n_corrections=3,
    )
    try:
        env.reset(seed=SEED)
        stars = [env.step(np.zeros(3, dtype=np.float32))[4]["theta_star"] for _ in range(3)]
    finally:
        env.close()
    np.testing.assert_array_equal(stars[1], -stars[0])
    np.testing.assert_array_equal(stars[2], stars[1])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"switch_after": -1}, "switch_after"), ({"theta_after": [1.0]}, "theta_after")],
)
def test_changing_human_bad_arguments(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ChangingHuman(RobotTask(), np.ones(2), np.random.default_rng(0), **kwargs)


# ---------------------------------------------------------------------- basin_map
def test_basin_map_shape_and_lambda_zero_is_gradient():
    task = RobotTask()
    grid = (np.linspace(-1, 1, 5), np.linspace(-1, 1, 3))
    g = basin_map(task, "gradient", grid, steps=3, seed=SEED)
    s0 = basin_map(task, make_learner("strol", task=task, lam=0.0), grid, steps=3, seed=SEED)
    s1 = basin_map(task, "strol", grid, steps=3, seed=SEED)
    assert g.error.shape == (3, 5) and g.converged.shape == (3, 5)
    np.testing.assert_array_equal(s0.error, g.error)
    assert not np.array_equal(s1.error, g.error)  # ĝ changes the dynamics


@pytest.mark.parametrize("learner", ["gradient", "strol"])
def test_basin_map_cell_at_theta_star_stays(learner):
    task = RobotTask()
    star = task.prior_modes[0]
    m = basin_map(task, learner, ([star[0]], [star[1]]), sigma=0.0, steps=4, seed=SEED)
    assert m.error[0, 0] == 0.0 and m.fraction_converged == 1.0


@pytest.mark.parametrize("grid", [0, 1, (5, 1), (1, 5)])
def test_basin_map_bad_grid(grid):
    with pytest.raises(ValueError, match=r"grid(\[\d\])? must be an integer >= 2"):
        basin_map(RobotTask(), "gradient", grid)


# ---------------------------------------------------------------------- the confirm analysis
def _records(deltas: dict[str, np.ndarray]) -> list[dict]:
    """Synthetic records: baselines regret 1 + noise; StROL = baseline's + delta."""
    rng = np.random.default_rng(SEED)
    out = []
    n = len(next(iter(deltas.values())))
    for cond, delta in deltas.items():
        base = 1.0 + rng.random(n)
        for learner in confirm.LEARNERS:
            vals = base + (delta if learner == "strol" else 0.0)
            for i, v in enumerate(vals):
                out.append(
                    {
                        "env": "robot",
                        "condition": cond,
                        "learner": learner,
                        "seed": i,
                        "regret": float(v),
                        "error": float(v),
                        "cos_error": float(v),
                    }
                )
    return out


def test_confirm_decision_rule_on_known_data():
    n = 40
    lower = -0.1 - np.random.default_rng(1).random(n) * 0.1
    dust = np.where(np.arange(n) % 2 == 0, 5e-7, -5e-7)  # within the tie tolerance
    res = confirm.analyse(
        _records({"training": lower, "clean": -lower, "noisy-biased": dust}),
        conditions=["training", "clean", "noisy-biased"],
        resamples=200,
    )
    assert res["verdicts"] == {
        "training": "confirmed",
        "clean": "contradicted",
        "noisy-biased": "not confirmed",
    }
    dust_rows = [r for r in res["rows"] if r["condition"] == "noisy-biased"]
    reg = [r for r in dust_rows if r["metric"] == "regret"]
    assert all(r["n_nonzero"] == 0 and r["wilcoxon_p_raw"] == 1.0 for r in reg)
    assert all(r["prob_improvement"] == 0.5 for r in reg)
    # the tie rule is for regret only: 1 − cos keeps the dust as real differences
    assert all(r["n_nonzero"] == n for r in dust_rows if r["metric"] == "cos_error")
    train = [r for r in res["rows"] if (r["condition"], r["metric"]) == ("training", "regret")]
    for r in train:
        assert r["prob_improvement"] == 1.0 and r["median_diff_ci95_high"] < 0


# ---------------------------------------------------------------------- the CLI presets
@pytest.mark.parametrize(
    ("argv", "stem"),
    [
        (
            ["changing", "--env", "robot", "--runs", "2", "--seed", str(SEED), "--jobs", "1"],
            "changing",
        ),
        (
            ["lambda", "--lambdas", "0,1", "--runs", "2", "--seed", str(SEED), "--jobs", "1"],
            "lambda",
        ),
        (["basin", "--grid", "4", "--steps", "2"], "basin"),
        (["confirm", "--runs", "2", "--seed", str(SEED), "--jobs", "1"], "confirm"),
    ],
)
def test_preset_writes_table_meta_and_plot(argv, stem, tmp_path, capsys):
    out = tmp_path / stem
    assert cli.main([*argv, "--out", str(out), *(["--quiet"] if stem != "basin" else [])]) == 0
    text = capsys.readouterr().out
    assert "wall time" in text
    for name in (f"{stem}.csv", f"{stem}.md", f"{stem}.json", f"plots/{stem}.png"):
        assert (out / name).is_file(), name
    meta = json.loads((out / f"{stem}.json").read_text())
    assert meta["preset"] == stem and "versions" in meta
    assert meta["kernels"] == float_kernels()  # which arithmetic made these numbers
    folders = list(out.glob("**/meta.json"))  # the runner's results folders (none for basin)
    assert folders or stem == "basin"
    assert all(json.loads(m.read_text())["kernels"] == float_kernels() for m in folders)
    if stem == "confirm":
        assert "EXPLORATORY" in text and meta["protocol"] is False
        assert meta["seeds"] == [SEED, SEED + 1]
    if stem == "changing":  # the authors' noise: absolute 0.025 over a_max 0.1 = 25 %
        assert meta["sigma"] == 0.25 and meta["switch_after"] == 2
        run_meta = json.loads((out / "meta.json").read_text())
        assert run_meta["config"]["experiments"][0]["condition"]["sigma"] == 0.25


def test_confirm_held_out_runs_its_cells_labelled_exploratory(tmp_path, capsys):
    """--protocol held-out: env × (Boltzmann, myopic, driver), the four learners, an "env"
    column; other seeds than 3_200_000 are exploratory."""
    out = tmp_path / "ho"
    argv = ["confirm", "--protocol", "held-out", "--env", "robot", "--runs", "2"]
    assert cli.main([*argv, "--seed", str(SEED), "--jobs", "1", "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "held-out humans — EXPLORATORY" in text
    meta = json.loads((out / "confirm.json").read_text())
    assert meta["protocol"] is False and meta["protocol_name"] == "held-out"
    assert set(meta["verdicts"]) == {f"robot/{h}" for h in confirm.HELD_OUT_HUMANS}
    conds = {e["condition"]["name"]: e["condition"] for e in meta["config"]["experiments"]}
    assert {c["human"] for c in conds.values()} == set(confirm.HELD_OUT_HUMANS)
    assert {c["sigma"] for c in conds.values()} == {0.25}  # the Robot's training noise
    assert (out / "confirm.csv").read_text().startswith("env,condition,metric,baseline")
    assert confirm.is_protocol(1000, confirm.HELD_OUT_SEED, "held-out")
    assert not confirm.is_protocol(1000, confirm.PROTOCOL_SEED, "held-out")


def test_confirm_held_out_uses_one_minus_cos_on_the_highway():
    """The Highway cells' verdicts come from 1 − cos (no regret there); the Robot's from
    regret; the sensitivity Holm spans every cell."""
    n = 30
    lower = -0.1 - np.random.default_rng(2).random(n) * 0.1
    recs = []
    for env in ("robot", "highway"):
        for r in _records({h: lower for h in confirm.HELD_OUT_HUMANS}):
            r = dict(r, env=env)
            if env == "highway":
                r["regret"] = float("nan")
                r["cos_error"] = 1.0 + (0.5 if r["learner"] == "strol" else 0.0)  # StROL higher
            recs.append(r)
    res = confirm.analyse_held_out(recs, ["robot", "highway"], resamples=200)
    for h in confirm.HELD_OUT_HUMANS:
        assert res["verdicts"][f"robot/{h}"] == "confirmed"
        assert res["verdicts"][f"highway/{h}"] == "contradicted"
    assert not any(r["env"] == "highway" and r["metric"] == "regret" for r in res["rows"])
    assert all("wilcoxon_p_holm_12" in r for r in res["rows"] if r["metric"] in ("regret",))


def test_lambda_sweeps_seven_values_by_default():
    args = cli.build_parser().parse_args(["lambda"])
    assert args.lambdas == [0.0, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["lambda", "--lambdas", "0,-1"], "--lambdas must be comma-separated finite numbers"),
        (["lambda", "--lambdas", "nan"], "--lambdas must be comma-separated finite numbers"),
        (["basin", "--grid", "0"], "--grid must be an integer >= 2"),
        (["basin", "--grid", "1"], "--grid must be an integer >= 2, got 1"),
        (["changing", "--runs", "0"], "--runs must be an integer >= 1"),
        (["changing", "--switch-after", "5"], "--switch-after must be below the 5 corrections"),
        (["confirm", "--runs", "0"], "--runs must be an integer >= 1"),
        (["confirm", "--env", "highway"], "--env must be robot for --protocol paper-conditions"),
        (["confirm", "--protocol", "nope"], "invalid choice: 'nope'"),
    ],
)
def test_preset_bad_input_exits_2_before_any_folder(argv, message, tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        cli.main([*argv, "--out", str(out)])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_reference_learner_has_one_definition():
    """confirm and compare_learners take the reference from conditions (no local literal);
    confirm's pre-registered reference stays "strol"."""
    import ast
    import inspect

    from lab.checks import compare_learners
    from strol_gym.benchmarks.engine import conditions

    for mod in (confirm, compare_learners):
        for node in ast.parse(inspect.getsource(mod)).body:
            if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "REFERENCE" for t in node.targets
            ):
                assert not isinstance(node.value, ast.Constant), mod.__name__
        assert mod.REFERENCE == conditions.REFERENCE_LEARNER
    assert confirm.REFERENCE == "strol"
    assert confirm.LEARNERS[-1] == "strol"
