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


def _requirements(*extras: str) -> dict[str, str]:
    """setup.cfg's install_requires (and the named extras') as {normalised name: specifier}."""
    import configparser

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    sections = [cfg["options"]["install_requires"]]
    sections += [cfg["options.extras_require"][extra] for extra in extras]
    lines = [x.split("#")[0].strip() for section in sections for x in section.splitlines()]
    reqs = [Requirement(ln) for ln in lines if ln]
    return {canonicalize_name(r.name): str(r.specifier) for r in reqs}


def _pins(name: str) -> dict[str, str]:
    """A constraints file of .ci/ (the lock, or the floors) as {normalised name: version}."""
    from packaging.utils import canonicalize_name

    text = (ROOT / ".ci" / name).read_text().splitlines()
    pins = [ln.split("==") for ln in text if ln.strip() and not ln.startswith("#")]
    assert all(len(p) == 2 for p in pins), f"{name} holds name==version lines only"
    return {canonicalize_name(name): version for name, version in pins}


def _lock() -> dict[str, str]:
    return _pins("constraints.txt")


FLOORED_EXTRAS = ("bench", "sb3")
"""The extras whose lower bounds .ci/oldest installs beside install_requires'."""


def test_ranges_start_at_the_floors_and_hold_the_lock():
    """Each lower bound (install_requires, [bench], [sb3]) is the version .ci/oldest installs
    (.ci/oldest.txt pins exactly those); no dependency is pinned; the lock lies in the ranges."""
    from packaging.specifiers import SpecifierSet

    floors, lock = _pins("oldest.txt"), _lock()
    requirements = _requirements(*FLOORED_EXTRAS)
    assert set(floors) == set(requirements), "the floors pin what setup.cfg bounds, nothing else"
    for name, spec in requirements.items():
        assert "==" not in spec, f"{name} is pinned ({spec}): declare a range"
        lower = [s[2:] for s in spec.split(",") if s.startswith(">=")]
        assert lower == [floors[name]], f"{name}{spec}: its lower bound is not {floors[name]}"
        assert lock[name] in SpecifierSet(spec), f"the lock's {name} {lock[name]} is not in {spec}"


def test_setup_installs_the_lock_and_keys_its_stamp_on_it():
    script = (ROOT / ".ci" / "setup").read_text()
    assert "lock=(-c .ci/constraints.txt)" in script
    installs = [
        ln for ln in script.splitlines() if "pip install" in ln and "--upgrade pip" not in ln
    ]
    assert installs and all('"${lock[@]}"' in ln for ln in installs)
    stamp = next(ln for ln in script.splitlines() if ln.startswith("want="))
    assert ".ci/constraints.txt" in stamp and "setup.cfg" in stamp


def _torch_pin(script: str) -> str:
    line = next(
        ln for ln in (ROOT / ".ci" / script).read_text().splitlines() if ln.startswith("TORCH=")
    )
    return line.split()[0].removeprefix("TORCH=")


def test_ci_ends_with_the_newest_release_and_oldest_legs():
    run = (ROOT / ".ci" / "run").read_text().splitlines()
    assert run[-3:] == ["bash .ci/newest", "bash .ci/release", "bash .ci/oldest"]


def test_the_newest_leg_keeps_the_locks_cpu_torch():
    """.ci/newest pre-installs exactly the lock's torch (the CPU wheel), installs strol-gym
    without the lock, and fails if torch was replaced."""
    script = (ROOT / ".ci" / "newest").read_text()
    assert _torch_pin("newest") == _lock()["torch"]
    assert 'pip install -q "torch==$TORCH"' in script
    assert "constraints" not in script.split("set -euo pipefail")[1]  # the ranges, not the lock
    assert 'if [ "$before" != "$after" ]' in script and "exit 1" in script
    for test in ("test_robot_env", "test_highway_env", "test_learners"):
        assert f"tests/{test}.py" in script
    assert 'strol-bench" paper' in script


def test_the_oldest_leg_installs_beside_a_researchers_stack_then_at_the_floors():
    """.ci/oldest: the wheel into a venv holding torch (the floor's) and numpy 2.2, with a
    constraints file pinning both, fails if either moved; then every floor of .ci/oldest.txt,
    checked installed, under the core tests and a paper run."""
    script = (ROOT / ".ci" / "oldest").read_text()
    assert _torch_pin("oldest") == _pins("oldest.txt")["torch"]
    numpy = next(ln for ln in script.splitlines() if ln.startswith("NUMPY="))
    assert numpy.split()[0].removeprefix("NUMPY=").startswith("2.2.")
    assert '-c "$tmp/stack.txt" "$wheel"' in script
    assert "-c .ci/oldest.txt" in script and "not at the floor" in script
    for test in ("test_robot_env", "test_highway_env", "test_learners", "test_vector_envs"):
        assert f"tests/{test}.py" in script
    assert 'strol-bench" paper' in script


def test_the_release_leg_builds_and_checks_the_wheel_the_oldest_leg_smoke_tests_it():
    """The release leg builds and checks; the oldest leg installs that wheel alone beside a
    researcher's torch and numpy and smoke-tests it there (one venv, not two)."""
    release = (ROOT / ".ci" / "release").read_text()
    for step in ("-m build", "twine check --strict dist/*", ".ci/check_dist.py dist"):
        assert step in release
    oldest = (ROOT / ".ci" / "oldest").read_text()
    step1 = oldest.split("Back to the researcher's stack")[0]
    assert 'ls "$repo"/dist/strol_gym-*.whl' in step1 and "smoke.py" in step1
    assert 'grep -q "strol-gym\\[bench\\]"' in step1  # strol-bench without [bench]: status 2
