"""``--backend ray`` runs the same units as ``local`` and stores identical records, resume
included; a user-registered learner reaches the Ray workers; the local cluster listens on loopback
only. Skipped where Ray is not installed (``pip install ".[ray]"``)."""

from __future__ import annotations

import ipaddress
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.engine.backends import check_backend
from strol_gym.benchmarks.engine.config import paper_config
from strol_gym.benchmarks.engine.kernels import kernel_label
from strol_gym.benchmarks.engine.runner import run_benchmark
from strol_gym.learners.registry import register_learner, unregister_learner

MY_LEARNER = "test-backend-gradient"


def _records(path: Path) -> dict[str, list]:
    return {
        p.name: json.loads(p.read_text())["records"]
        for p in sorted((path / "records").glob("*.json"))
    }


def test_an_unknown_backend_or_a_stray_address_is_a_value_error():
    with pytest.raises(ValueError, match="backend must be one of"):
        check_backend("spark", None)
    with pytest.raises(ValueError, match="ray_address is only used with backend 'ray'"):
        check_backend("local", "127.0.0.1:6379")


def test_the_cli_rejects_an_unknown_backend_with_status_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(["paper", "--env", "robot", "--backend", "spark"])
    assert e.value.code == 2
    assert "--backend" in capsys.readouterr().err


@pytest.fixture(scope="module")
def ray_cluster():
    pytest.importorskip("ray", reason="Ray is not installed (pip install '.[ray]')")
    import ray

    from strol_gym.benchmarks.engine.backends import _start_ray

    started = _start_ray(2, None)  # both runs below reuse this local cluster
    yield ray
    if started:
        ray.shutdown()


@pytest.fixture(scope="module")
def config():
    register_learner(MY_LEARNER, "strol_gym.learners.rules:GradientLearner")
    cfg = paper_config(
        ["highway"], runs=3, learners=(MY_LEARNER, "mof"), block=1, reference=MY_LEARNER
    )
    yield type(cfg)(cfg.experiments[:1], cfg.learners, cfg.reference, cfg.block)
    unregister_learner(MY_LEARNER)


def test_ray_gives_the_records_of_local_resume_included(ray_cluster, config, tmp_path):
    local = run_benchmark(config, tmp_path / "local", jobs=1, quiet=True)
    assert local.meta["config"]["plugins"]["learner"] == {
        MY_LEARNER: "strol_gym.learners.rules:GradientLearner"
    }  # the user's learner travels to the workers as data

    class Stop(Exception):
        pass

    def stop_after_one(unit, n):
        if n == 1:
            raise Stop

    out = tmp_path / "ray"
    with pytest.raises(Stop):
        run_benchmark(config, out, jobs=1, quiet=True, on_unit=stop_after_one)
    ran = []
    run_benchmark(
        config, out, jobs=2, quiet=True, backend="ray", on_unit=lambda u, n: ran.append(u)
    )
    assert len(ran) == len(config.units()) - 1  # the resume ran only the missing units, on Ray
    assert _records(out) == _records(tmp_path / "local")
    # Each unit names the kernels of the process that computed it: here Ray workers.
    units = [json.loads(p.read_text()) for p in (out / "records").glob("*.json")]
    assert {u["kernels"] for u in units} == {kernel_label()}
    assert json.loads((out / "meta.json").read_text())["status"] == "complete"


def _descendants(pid: int) -> set[int]:
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        out.add(p)
        todo += children.get(p, [])
    return out


def test_the_local_cluster_listens_on_loopback_only(ray_cluster):
    if shutil.which("ss") is None:
        pytest.skip("needs ss (iproute2) to list listening sockets")
    ours = _descendants(os.getpid())
    listening = subprocess.run(["ss", "-tlnpH"], capture_output=True, text=True, check=True)
    seen = 0
    for line in listening.stdout.splitlines():
        pids = {int(p) for p in re.findall(r"pid=(\d+)", line)}
        if not pids & ours:
            continue
        seen += 1
        host = line.split()[3].rsplit(":", 1)[0].strip("[]").split("%")[0]
        assert host != "*", line
        addr = ipaddress.ip_address(host)
        addr = getattr(addr, "ipv4_mapped", None) or addr  # [::ffff:127.0.0.1] is loopback too
        assert addr.is_loopback, line
    assert seen, "found no listening socket of the Ray cluster"
