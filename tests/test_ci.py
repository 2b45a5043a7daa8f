"""CI runs exactly the README's second command: lint, format check, then the tests."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _ci_command() -> str:
    text = (ROOT / ".ci" / "run").read_text().replace("\\\n", " ")
    lines = [ln for ln in text.splitlines() if ln.strip().startswith("bash .ci/setup")]
    assert len(lines) == 1, ".ci/run should hold one command that starts with bash .ci/setup"
    return " ".join(lines[0].split())


def test_readme_second_command_is_what_ci_runs() -> None:
    blocks = re.findall(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    assert len(blocks) >= 2, "README should start with two bash commands"
    assert " ".join(blocks[1].split()) == _ci_command()


def test_ci_lints_and_checks_format_before_the_tests() -> None:
    steps = [s.strip() for s in _ci_command().split("&&")]
    ruff_check = steps.index(".venv/bin/python -m ruff check .")
    ruff_format = steps.index(".venv/bin/python -m ruff format --check .")
    tests = next(i for i, s in enumerate(steps) if "-m pytest" in s)
    assert ruff_check < tests and ruff_format < tests


def test_ci_reruns_the_kernel_sensitive_tests_under_other_kernels() -> None:
    """After the suite, the tests that compare numbers across batches, jobs, resumes and Ray run
    again under other OpenBLAS and torch kernels (SkylakeX only where the CPU has AVX-512)."""
    steps = [s.strip() for s in _ci_command().split("&&")]
    assert steps[-1] == "bash .ci/kernels"
    script = (ROOT / ".ci" / "kernels").read_text()
    for name in ("test_planning", "test_bench_runner", "test_backend", "test_bench_e2e"):
        assert f"tests/{name}.py" in script
    for setting in ("Prescott:default", "Haswell:default", "SkylakeX:avx512"):
        assert setting in script
    assert "grep -qw avx512f /proc/cpuinfo" in script


def _requirements() -> dict[str, str]:
    """setup.cfg's install_requires as {normalised name: specifier}."""
    import configparser

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    lines = cfg["options"]["install_requires"].splitlines()
    reqs = [Requirement(ln) for ln in (x.split("#")[0].strip() for x in lines) if ln]
    return {canonicalize_name(r.name): str(r.specifier) for r in reqs}


def _lock() -> dict[str, str]:
    from packaging.utils import canonicalize_name

    text = (ROOT / ".ci" / "constraints.txt").read_text().splitlines()
    pins = [ln.split("==") for ln in text if ln.strip() and not ln.startswith("#")]
    assert all(len(p) == 2 for p in pins), "the lock holds name==version lines only"
    return {canonicalize_name(name): version for name, version in pins}


def test_ranges_start_at_the_lock_and_pin_nothing():
    """Each lower bound is the version the lock's CI leg runs; no dependency is pinned."""
    lock = _lock()
    for name, spec in _requirements().items():
        assert "==" not in spec, f"{name} is pinned ({spec}): declare a range"
        lower = [s[2:] for s in spec.split(",") if s.startswith(">=")]
        assert lower == [lock[name]], (
            f"{name}{spec}: its lower bound is not the lock's {lock[name]}"
        )


def test_setup_installs_the_lock_and_keys_its_stamp_on_it():
    script = (ROOT / ".ci" / "setup").read_text()
    assert "lock=(-c .ci/constraints.txt)" in script
    installs = [
        ln for ln in script.splitlines() if "pip install" in ln and "--upgrade pip" not in ln
    ]
    assert installs and all('"${lock[@]}"' in ln for ln in installs)
    stamp = next(ln for ln in script.splitlines() if ln.startswith("want="))
    assert ".ci/constraints.txt" in stamp and "setup.cfg" in stamp


def test_ci_runs_the_newest_leg_with_the_lowest_torch():
    """.ci/run ends with the newest-versions leg; it pre-installs exactly torch's lower bound,
    installs strol-gym without the lock, and fails if torch was replaced."""
    run = (ROOT / ".ci" / "run").read_text().splitlines()
    assert run[-1] == "bash .ci/newest"
    script = (ROOT / ".ci" / "newest").read_text()
    torch_pin = next(ln for ln in script.splitlines() if ln.startswith("TORCH="))
    assert torch_pin.split()[0] == "TORCH=" + _requirements()["torch"].removeprefix(">=")
    assert 'pip install -q "torch==$TORCH"' in script
    assert "constraints" not in script.split("set -euo pipefail")[1]  # the ranges, not the lock
    assert 'if [ "$before" != "$after" ]' in script and "exit 1" in script
    for test in ("test_robot_env", "test_highway_env", "test_learners"):
        assert f"tests/{test}.py" in script
    assert 'strol-bench" paper' in script
