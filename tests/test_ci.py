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
