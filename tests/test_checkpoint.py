"""ĝ checkpoints on disk: the shipped safetensors weights, loading without an unpickler, a
user's own torch ``.pt`` checkpoints, and the ``.pt`` → ``.safetensors`` conversion."""

from __future__ import annotations

import json
import pickle
import shutil

import pytest
import torch
from strol_gym.benchmarks.engine.provenance import learner_fingerprint

from strol_gym.learners import checkpoint as ckpt
from strol_gym.learners.network import CorrectionNet
from strol_gym.learners.registry import make_learner
from strol_gym.tasks import make_task
from strol_gym.tasks.robot import RobotTask
from strol_gym.tasks.study import STUDY_TASKS_V1

ROBOT = RobotTask()


def _shipped() -> list[tuple[ckpt.Path, dict]]:
    return [
        (side.with_suffix(".safetensors"), json.loads(side.read_text()))
        for side in sorted(ckpt.PRETRAINED_DIR.glob("*.json"))
    ]


def _model(seed: int = 3) -> CorrectionNet:
    torch.manual_seed(seed)
    return CorrectionNet(ROBOT.network_input_dim, ROBOT.dim)


def test_every_shipped_weights_file_is_safetensors_beside_its_sidecar():
    names = {p.name for p in ckpt.PRETRAINED_DIR.iterdir() if not p.name.startswith("_")}
    assert not [n for n in names if n.endswith(".pt")]
    stems = {n.rsplit(".", 1)[0] for n in names}
    assert names == {f"{s}{ext}" for s in stems for ext in (".json", ".safetensors")}
    for weights, meta in _shipped():
        assert meta["weights_sha256"] == ckpt.weights_sha256(weights), weights.name


def test_shipped_weights_load_without_an_unpickler(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("an unpickler was used")

    for name in ("load", "loads", "Unpickler"):
        monkeypatch.setattr(pickle, name, refuse)
    monkeypatch.setattr(torch, "load", refuse)
    v1 = {t.task_id: t for t in STUDY_TASKS_V1.values()}  # unregistered study Tasks
    shipped = _shipped()
    assert len(shipped) >= 6
    for weights, meta in shipped:
        tid = meta["task"]["task_id"]
        task = v1[tid]() if tid in v1 else make_task(tid)
        model, _ = ckpt.load_checkpoint(weights, task, meta["kind"])
        assert model.out_dim == task.dim


def test_converting_a_pt_gives_the_bytes_training_writes(tmp_path):
    """``--convert`` and ``save_checkpoint`` share one writer: a converted checkpoint is the
    file training would have written for the same tensors, sidecar included."""
    model = _model()
    pt = ckpt.save_checkpoint(tmp_path / "a.pt", model, ROBOT, "strol", {"seed": 1})
    trained = ckpt.save_checkpoint(tmp_path / "b.safetensors", model, ROBOT, "strol", {"seed": 1})
    assert ckpt.main(["--convert", str(pt)]) is None
    converted = pt.with_suffix(".safetensors")
    assert converted.read_bytes() == trained.read_bytes()
    assert ckpt.read_sidecar(converted) == ckpt.read_sidecar(trained)
    before, after = ckpt.read_weights(pt), ckpt.read_weights(converted)
    assert before.keys() == after.keys()
    for key, value in before.items():
        assert after[key].dtype == value.dtype
        assert after[key].numpy().tobytes() == value.numpy().tobytes()
    ckpt.load_checkpoint(converted, ROBOT, "strol")


def test_convert_refuses_weights_their_sidecar_does_not_vouch_for(tmp_path, capsys):
    pt = ckpt.save_checkpoint(tmp_path / "a.pt", _model(), ROBOT, "strol")
    other = _model(seed=4).state_dict()
    torch.save(other, pt)
    with pytest.raises(SystemExit) as e:
        ckpt.main(["--convert", str(pt)])
    assert e.value.code == 2
    assert "the weights do not match their sidecar" in capsys.readouterr().err
    assert not pt.with_suffix(".safetensors").exists()
    with pytest.raises(ValueError, match=r"--convert takes a \.pt checkpoint"):
        ckpt.convert_to_safetensors(tmp_path / "a.json")


class _Boom:
    ran = False

    def __reduce__(self):
        return (_Boom._explode, ())

    @staticmethod
    def _explode():  # pragma: no cover - must never run
        _Boom.ran = True


def test_a_users_pt_loads_with_weights_only_and_code_in_it_never_runs(tmp_path):
    path = ckpt.save_checkpoint(tmp_path / "mine.pt", _model(), ROBOT, "strol")
    learner = make_learner("strol", task=ROBOT, checkpoint=path)
    assert learner.checkpoint == str(path)
    weights = ckpt.read_weights(path)
    torch.save({**weights, "payload": _Boom()}, path)
    ckpt.rehash_sidecar(path)
    with pytest.raises(ValueError, match=rf"{path}: cannot read these weights"):
        ckpt.load_checkpoint(path, ROBOT, "strol")
    assert not _Boom.ran


def test_a_damaged_safetensors_file_is_refused_naming_it(tmp_path):
    path = ckpt.save_checkpoint(tmp_path / "w.safetensors", _model(), ROBOT, "strol")
    data = path.read_bytes()
    # a header that claims 2**40 bytes, and a file cut short inside its tensors
    for damaged in ((2**40).to_bytes(8, "little") + data[8:], data[: len(data) // 2]):
        path.write_bytes(damaged)
        ckpt.rehash_sidecar(path)
        with pytest.raises(ValueError, match=rf"{path}: cannot read these weights"):
            ckpt.load_checkpoint(path, ROBOT, "strol")


def test_the_learner_fingerprint_covers_weights_and_sidecar(tmp_path):
    src = ckpt.find_pretrained(ROBOT, "strol")
    for suffix in (".safetensors", ".json"):
        shutil.copy(src.with_suffix(suffix), tmp_path / f"w{suffix}")
    path = tmp_path / "w.safetensors"
    before = learner_fingerprint(make_learner("strol", task=ROBOT, checkpoint=path))
    assert before == learner_fingerprint(make_learner("strol", task=ROBOT))
    meta = ckpt.read_sidecar(path)
    meta["training"]["note"] = "edited"  # loads as before, but it is not the same checkpoint
    ckpt.sidecar_path(path).write_text(json.dumps(meta))
    after = learner_fingerprint(make_learner("strol", task=ROBOT, checkpoint=path))
    assert after["checkpoint_sha256"] != before["checkpoint_sha256"]


def test_weights_paths_name_both_formats():
    assert ckpt.WEIGHTS_SUFFIXES[0] == ".safetensors"  # the default, what training writes
    for bad in ("w.bin", "w"):
        with pytest.raises(ValueError, match=r"ending in \.safetensors \(or \.pt"):
            ckpt.check_weights_path(bad)
