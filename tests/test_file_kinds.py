"""Only regular files are replaced and only regular files are read.

A write never turns a device node, a FIFO, a socket, a directory or a symbolic link into our
file (``files.write_atomic`` and every writer through it); a read never opens a FIFO or a device
(it would block, or never end); the authors' pickles cannot unfold through shared references;
a Minari dataset's HDF5 file keeps its arrays inside it and within the caps.
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import socket
import stat
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from cli_checks import cli_error

from strol_gym import files
from strol_gym.benchmarks.sessions.plain_pickle import PickleRefused, load_plain_pickle


def _not_regular(tmp_path: Path) -> dict[str, Path]:
    """A FIFO, a symbolic link (to a file that must stay as it is), a directory and a socket;
    with root, a character device made with mknod here (never under /dev)."""
    made = {}
    made["fifo"] = tmp_path / "fifo"
    os.mkfifo(made["fifo"])
    (tmp_path / "target").write_text("theirs")
    made["link"] = tmp_path / "link"
    made["link"].symlink_to(tmp_path / "target")
    made["dir"] = tmp_path / "dir"
    made["dir"].mkdir()
    made["socket"] = tmp_path / "sock"
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(made["socket"]))
    s.close()
    if os.geteuid() == 0:
        made["device"] = tmp_path / "null"
        os.mknod(made["device"], 0o600 | stat.S_IFCHR, os.makedev(1, 3))  # /dev/null's numbers
    return made


def _same(tmp_path: Path, made: dict[str, Path], modes: dict[str, int]) -> None:
    for name, path in made.items():
        assert os.lstat(path).st_mode == modes[name], name
    assert (tmp_path / "target").read_text() == "theirs"
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_the_one_writer_replaces_regular_files_only(tmp_path):
    made = _not_regular(tmp_path)
    modes = {k: os.lstat(p).st_mode for k, p in made.items()}
    for path in made.values():
        with pytest.raises(files.NotAFile, match=rf"{path} is .*not a regular file"):
            files.write_json_atomic(path, {"a": 1})
        with pytest.raises(files.NotAFile, match=str(path)):
            with files.open_atomic(path) as f:
                f.write("x")
    _same(tmp_path, made, modes)
    ours = tmp_path / "ours.json"
    files.write_json_atomic(ours, [1])
    files.write_json_atomic(ours, [2])  # a regular file is replaced
    assert json.loads(ours.read_text()) == [2]


def test_a_path_turned_into_a_fifo_during_the_write_is_not_replaced(tmp_path):
    path = tmp_path / "out.json"

    def write(tmp: Path) -> None:
        tmp.write_text("{}")
        os.mkfifo(path)  # appears while the temporary is written

    with pytest.raises(files.NotAFile, match="FIFO"):
        files.write_atomic(path, write)
    assert stat.S_ISFIFO(os.lstat(path).st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]


def test_fit_participant_and_train_refuse_a_fifo_or_a_link_at_out(tmp_path, capsys):
    made = _not_regular(tmp_path)
    modes = {k: os.lstat(p).st_mode for k, p in made.items()}
    logs = tmp_path / "logs"
    logs.mkdir()
    for path in made.values():
        err = cli_error(["fit-participant", str(logs), "--out", str(path)], capsys)
        assert str(path) in err and "not a regular file" in err
    link = tmp_path / "w.safetensors"
    link.symlink_to(tmp_path / "target")
    err = cli_error(["train", "--out", str(link)], capsys)
    assert str(link) in err and "symbolic link" in err
    _same(tmp_path, made, modes)


def test_readers_open_regular_files_only(tmp_path):
    """A FIFO (reading it would wait for a writer) and a link to a device (its bytes never end)
    are refused by name at once by every reader of bytes."""
    from strol_gym.benchmarks.engine import lock, slurm
    from strol_gym.envs.study.population import read_fit
    from strol_gym.learners.checkpoint import read_weights, weights_sha256
    from strol_gym.wrappers.session_log import SessionLogError, read_session

    fifo = tmp_path / "x.safetensors"
    os.mkfifo(fifo)
    zero = tmp_path / "zero.jsonl"
    zero.symlink_to("/dev/zero")
    t0 = time.monotonic()
    for path in (fifo, zero):
        with pytest.raises(files.NotAFile, match=f"{path} is a (FIFO|character device)"):
            files.read_regular(path)
        with pytest.raises(SessionLogError, match="not a regular file"):
            read_session(path)
        with pytest.raises(ValueError, match="not a regular file"):
            read_fit(path)
        with pytest.raises(ValueError, match="not a regular file"):
            read_weights(path)
        with pytest.raises(files.NotAFile):
            weights_sha256(path)
        with pytest.raises(files.NotAFile):
            lock._read(path)
        with pytest.raises(PickleRefused, match="not a regular file"):
            load_plain_pickle(path)
    assert slurm._read_block(fifo, None, "h") is None  # type: ignore[arg-type]  # ignored
    assert time.monotonic() - t0 < 5


def test_a_fifo_among_the_study_files_is_named_not_skipped(tmp_path, capsys):
    root = tmp_path / "data"
    (root / "user_1" / "task_1" / "b1").mkdir(parents=True)
    os.mkfifo(root / "user_1" / "task_1" / "b1" / "data.pkl")
    err = cli_error(["import-study", str(root), "--out", str(tmp_path / "out")], capsys)
    assert "data.pkl is a FIFO" in err


def _unfolding_pickle(levels: int = 30) -> bytes:
    """A study log in the authors' layout whose trajectory is ``levels`` nested lists of
    ``[prev, prev]``: a few hundred bytes that unfold to 2**levels leaves when copied."""
    nested: list = [0.5]
    for _ in range(levels - 1):
        nested = [nested, nested]
    return pickle.dumps({"robot_traj": [nested], "corrections": [[]]}, protocol=2)


def test_the_unfolding_pickle_is_refused_fast_in_little_memory(tmp_path, capsys):
    root = tmp_path / "data"
    folder = root / "user_1" / "task_1" / "b1"
    folder.mkdir(parents=True)
    raw = _unfolding_pickle()
    assert len(raw) < 400
    (folder / "data.pkl").write_bytes(raw)
    from strol_gym.benchmarks.sessions import import_study  # noqa: F401  (imported: not timed)

    t0 = time.monotonic()
    err = cli_error(["import-study", str(root), "--out", str(tmp_path / "out")], capsys)
    assert time.monotonic() - t0 < 10
    assert "data.pkl" in err and "shared references" in err
    tracemalloc.start()
    try:
        with pytest.raises(PickleRefused):
            load_plain_pickle(folder / "data.pkl")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2**27  # the reader's own allocations: far below 1 GB


def test_shared_objects_stay_shared_and_count_as_often_as_referenced(tmp_path):
    row = np.arange(3.0)
    shared = [row, row]
    path = tmp_path / "x.pkl"
    path.write_bytes(pickle.dumps({"a": shared, "b": shared}))
    got = load_plain_pickle(path)
    assert got["a"] is got["b"] and got["a"][0] is got["a"][1]
    assert np.array_equal(got["b"][1], row)
    # 1 dict + 2 references to (1 list + 2 arrays) = 7 values
    assert load_plain_pickle(path, max_nodes=7)["a"][0] is not None
    with pytest.raises(PickleRefused, match="more than 6 values"):
        load_plain_pickle(path, max_nodes=6)


# ---------------------------------------------------------------------- Minari datasets
minari = pytest.importorskip("minari", reason='Minari is not installed (pip install ".[data]")')
h5py = pytest.importorskip("h5py")


BOX = json.dumps({"type": "Box", "shape": [2], "dtype": "float64", "low": [0, 0], "high": [1, 1]})


@pytest.fixture
def exported(tmp_path) -> Path:
    """A dataset folder the gate reads: metadata with both spaces, an HDF5 file of one
    episode (what is under test is the gate, not Minari: no export needed)."""
    folder = tmp_path / "base"
    (folder / "data").mkdir(parents=True)
    meta = {"observation_space": BOX, "action_space": BOX, "total_episodes": 1}
    meta.update(data_format="hdf5", total_steps=3, dataset_id="strol/kinds-v0")
    meta["minari_version"] = minari.__version__  # Minari goes on to open main_data.hdf5
    (folder / "data" / "metadata.json").write_text(json.dumps(meta))
    with h5py.File(folder / "data" / "main_data.hdf5", "w") as f:
        f.create_group("episode_0").create_dataset("actions", data=np.zeros((3, 2)))
    return folder


def _copy(exported: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "ds"
    shutil.copytree(exported, folder)
    return folder


def test_replay_of_a_dataset_whose_hdf5_file_is_a_fifo_exits_2_at_once(exported, tmp_path, capsys):
    folder = _copy(exported, tmp_path)
    data = folder / "data" / "main_data.hdf5"
    data.unlink()
    os.mkfifo(data)
    from strol_gym.benchmarks.sessions import export, replay  # noqa: F401  (imported: not timed)

    t0 = time.monotonic()
    err = cli_error(
        ["replay", str(folder), "--learners", "strol", "--out", str(tmp_path / "r"), "--no-plots"],
        capsys,
    )
    assert time.monotonic() - t0 < 10
    assert "main_data.hdf5 is a FIFO" in err


@pytest.mark.parametrize("how", ["external-link", "virtual", "external-storage", "declared"])
def test_hdf5_arrays_from_other_files_or_too_large_in_all_are_refused(
    how, exported, tmp_path, capsys
):
    from strol_gym.benchmarks.sessions.export import read_dataset

    folder = _copy(exported, tmp_path)
    data = folder / "data" / "main_data.hdf5"
    other = tmp_path / "other.bin"
    other.write_bytes(bytes(800))
    with h5py.File(data, "a") as f:
        ep = f["episode_0"]
        if how == "external-link":
            ep["extra"] = h5py.ExternalLink(str(other), "/x")
        elif how == "virtual":
            layout = h5py.VirtualLayout(shape=(10,), dtype="f8")
            layout[:] = h5py.VirtualSource(str(other), "x", shape=(10,))
            ep.create_virtual_dataset("extra", layout)
        elif how == "external-storage":
            ep.create_dataset("extra", shape=(100,), dtype="f8", external=[(str(other), 0, 800)])
        else:  # 300 chunked arrays never written, each within the per-array cap: 7 GB in all
            for i in range(300):
                ep.create_dataset(f"x{i}", shape=(10**6, 3), dtype="f8", chunks=(1024, 3))
    assert data.stat().st_size < 10**7
    words = {
        "external-link": "external link",
        "virtual": "virtual dataset",
        "external-storage": "external storage",
        "declared": "declare more than 1,073,741,824 bytes",
    }[how]
    with pytest.raises(ValueError, match=words):
        read_dataset(str(folder))
    err = cli_error(
        ["replay", str(folder), "--learners", "strol", "--out", str(tmp_path / "r"), "--no-plots"],
        capsys,
    )
    assert words in err


def test_a_memory_error_in_a_reader_is_one_line(exported, tmp_path, monkeypatch, capsys):
    from strol_gym.benchmarks.sessions import export

    def exhausted(*_a, **_k):
        raise MemoryError

    monkeypatch.setattr(export, "read_dataset", exhausted)
    err = cli_error(
        ["replay", str(exported), "--learners", "strol", "--out", str(tmp_path / "r")], capsys
    )
    assert "out of memory" in err


def test_the_study_servers_plan_and_consent_are_read_as_regular_files_only(tmp_path):
    from strol_gym.benchmarks.serve.plan import load_plan

    fifo = tmp_path / "plan.json"
    os.mkfifo(fifo)
    with pytest.raises(files.NotAFile, match=f"--study {fifo} is a FIFO"):
        load_plan(fifo)
    plan = tmp_path / "ok.json"
    plan.write_text(json.dumps({"name": "kinds", "consent": "consent.txt"}))
    os.mkfifo(tmp_path / "consent.txt")
    with pytest.raises(files.NotAFile, match=r"consent\.txt is a FIFO"):
        load_plan(plan)
