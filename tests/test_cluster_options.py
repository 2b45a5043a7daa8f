"""The cluster options do what they say or refuse: ``--backend slurm`` needs Slurm's ``sbatch``
(unless the executor is ``local``), ``--slurm-*`` options need ``--backend slurm``, a failing
``sbatch`` is one line, the partition is a name, and a ``--ray-address`` whose service is not
Ray fails within a deadline."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading

import pytest
from cli_checks import cli_error

RUN = ["run", "--env", "robot", "--learners", "gradient", "--runs", "2", "--block", "2"]


def test_backend_slurm_without_sbatch_is_refused_naming_it(tmp_path, monkeypatch, capsys):
    pytest.importorskip("submitit")
    monkeypatch.setenv("PATH", str(tmp_path))  # no sbatch here
    err = cli_error([*RUN, "--backend", "slurm", "--out", str(tmp_path / "o")], capsys)
    assert "needs Slurm: sbatch and srun not on PATH" in err and "--slurm-executor local" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "extra", [["--slurm-time", "5"], ["--slurm-executor", "local"], ["--slurm-partition", "gpu"]]
)
def test_slurm_options_without_backend_slurm_are_refused(extra, tmp_path, capsys):
    err = cli_error([*RUN, *extra, "--out", str(tmp_path / "o")], capsys)
    assert f"{extra[0]} only apply with --backend slurm" in err


@pytest.mark.parametrize("bad", ["gpu\n#SBATCH --mem=1T", "a b", "", "x;rm"])
def test_a_partition_is_a_name(bad, tmp_path, capsys):
    argv = [*RUN, "--backend", "slurm", "--slurm-partition", bad, "--out", str(tmp_path / "o")]
    assert "--slurm-partition" in cli_error(argv, capsys)


def test_a_failing_sbatch_is_one_line(tmp_path, monkeypatch, capsys):
    pytest.importorskip("submitit")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    sbatch = bin_dir / "sbatch"
    sbatch.write_text("#!/bin/sh\necho 'sbatch: error: invalid partition specified' >&2\nexit 1\n")
    sbatch.chmod(0o755)
    (bin_dir / "srun").symlink_to(sbatch)  # submitit looks for srun before it submits
    monkeypatch.setenv("PATH", f"{bin_dir}:/usr/bin:/bin")
    argv = [*RUN, "--backend", "slurm", "--quiet", "--no-plots", "--out", str(tmp_path / "o")]
    err = cli_error(argv, capsys)
    assert "could not be submitted" in err and "invalid partition specified" in err


def _not_ray_server() -> tuple[socket.socket, int]:
    """A server on 127.0.0.1 that answers an HTTP/2 preface with a SETTINGS frame (as any gRPC
    server does) and then nothing: it passes the reachability check and is not Ray."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)

    def serve() -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            try:
                conn.recv(4096)
                conn.sendall(bytes.fromhex("000000040000000000"))
            except OSError:
                pass  # kept open (and unanswered) until the server closes

    threading.Thread(target=serve, daemon=True).start()
    return server, server.getsockname()[1]


def test_a_ray_address_that_is_not_ray_fails_within_the_deadline():
    pytest.importorskip("ray")
    server, port = _not_ray_server()
    # In a fresh process: the abandoned ray.init thread must not share this one's Ray state.
    code = (
        "import sys\n"
        "from strol_gym.benchmarks.engine import backends\n"
        "backends.RAY_INIT_DEADLINE = 3.0\n"
        f"address = '127.0.0.1:{port}'\n"
        "backends.check_backend('ray', address)  # passes: it answers like gRPC\n"
        "import ray, time  # imported first: its import is not ray.init's wait\n"
        "t0 = time.monotonic()\n"
        "try:\n"
        "    backends._start_ray(1, address)\n"
        "except ValueError as e:\n"
        "    print(e)\n"
        "    print(f'after {time.monotonic() - t0:.1f} s')\n"
        "    sys.exit(2)\n"
    )
    try:
        proc = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
        )
    finally:
        server.close()
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert f"127.0.0.1:{port}: no Ray cluster answered within 3 s" in proc.stdout
    waited = float(proc.stdout.split("after ")[-1].split(" s")[0])
    assert 3.0 <= waited < 10.0
