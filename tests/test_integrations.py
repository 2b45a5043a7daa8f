"""Integrations as their users expect them: ``report --plugin`` keeps a user learner's display
name, Fig. 4 is one figure (not a copy of a bar grid) and readable with one condition."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from strol_gym.benchmarks.analysis import plots
from strol_gym.benchmarks.cli import main

from strol_gym.learners.registry import unregister_learner

PLUGIN = """
from strol_gym.learners.registry import register_learner

register_learner("normgrad", "strol_gym.learners.rules:GradientLearner", display="NormGrad")
"""


@pytest.fixture(scope="module")
def run_with_plugin(tmp_path_factory) -> tuple[Path, Path]:
    """A one-condition Robot run of gradient and a plugin's learner (display "NormGrad")."""
    root = tmp_path_factory.mktemp("plugin")
    plugin = root / "mine_report.py"
    plugin.write_text(PLUGIN)
    out = root / "res"
    argv = ["run", "--env", "robot", "--learners", "gradient,normgrad", "--reference", "gradient"]
    argv += ["--runs", "3", "--jobs", "1", "--quiet", "--plugin", str(plugin), "--out", str(out)]
    assert main(argv) == 0
    return out, plugin


def test_report_plugin_keeps_display_names(run_with_plugin):
    out, plugin = run_with_plugin
    assert "NormGrad" in (out / "summary.md").read_text()
    unregister_learner("normgrad")  # as in a new process
    del sys.modules[plugin.stem]
    assert main(["report", str(out), "--no-plots"]) == 0
    assert "NormGrad" not in (out / "summary.md").read_text()  # without the plugin: its name
    assert main(["report", str(out), "--no-plots", "--plugin", str(plugin)]) == 0
    assert "NormGrad" in (out / "summary.md").read_text()


def test_fig4_is_one_figure_and_readable_with_one_condition(run_with_plugin, monkeypatch):
    """Robot alone: Fig. 4 is its regret grid, so no bars_regret copy; the other metrics'
    grids are there; the one-column figure's title fits inside it."""
    out, plugin = run_with_plugin
    figures = {}
    save = plots.save_figure

    def keep(fig, folder, stem):
        if fig._suptitle is not None:
            fig.canvas.draw()
            title = fig._suptitle.get_window_extent()
            figures[stem] = (title, fig.bbox.bounds, len(fig._suptitle.get_text().splitlines()))
        return save(fig, folder, stem)

    monkeypatch.setattr(plots, "save_figure", keep)
    assert main(["report", str(out), "--plugin", str(plugin)]) == 0
    names = {p.name for p in (out / "plots").glob("*.png")}
    assert {"fig4.png", "bars_error.png", "bars_cos_error.png"} <= names
    assert "bars_regret.png" not in names
    fig4 = (out / "plots" / "fig4.png").read_bytes()
    assert all(fig4 != (out / "plots" / n).read_bytes() for n in names - {"fig4.png"})
    title, (x0, _, width, _), lines = figures["fig4"]
    assert lines > 1 and x0 <= title.x0 and title.x1 <= x0 + width


def test_minari_export_records_algorithm_and_recovers_env(tmp_path, monkeypatch, capsys):
    """``export --env``: the learner is the dataset's algorithm; its env_spec names our env,
    kwargs and learner wrapper only, so ``recover_environment()`` builds a working env whose
    θ̂ comes from that learner; an env_spec tampered with afterwards is refused."""
    minari = pytest.importorskip("minari")
    import json

    import numpy as np
    from cli_checks import cli_error

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    argv = ["export", "strol/runs-v0", "--env", "robot", "--learner", "gradient", "--runs", "2"]
    assert main(argv) == 0
    meta_path = tmp_path / "minari" / "strol" / "runs-v0" / "data" / "metadata.json"
    meta = json.loads(meta_path.read_text())
    assert meta["algorithm_name"] == "gradient"
    dataset = minari.load_dataset("strol/runs-v0")
    env = dataset.recover_environment()
    assert env.spec.id == "StROL-Robot-v0" and type(env.learner).__name__ == "GradientLearner"
    assert dataset.observation_space == env.observation_space
    assert dataset.action_space == env.action_space
    task = env.unwrapped.task
    for ep in dataset.iterate_episodes():  # φ of the logged x; the action is the env's (scaled)
        np.testing.assert_array_equal(
            ep.observations["phi"], task.features(ep.infos["x"]).astype(np.float32)
        )
        u_r = ep.infos["u_r"][:-1] / task.robot_action_bound
        np.testing.assert_array_equal(ep.actions, u_r.astype(np.float32))
        assert env.action_space.contains(ep.actions[0])
    obs, _ = env.reset(seed=7)
    obs, _, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    np.testing.assert_array_equal(obs["theta_hat"], info["theta_hat"].astype(np.float32))
    env.close()
    spec = json.loads(meta["env_spec"])
    spec["additional_wrappers"][0]["entry_point"] = "os:system"
    meta_path.write_text(json.dumps({**meta, "env_spec": json.dumps(spec)}))
    line = cli_error(["replay", "strol/runs-v0", "--learners", "gradient"], capsys)
    assert str(meta_path) in line and "additional_wrappers[0]" in line
