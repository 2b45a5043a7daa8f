"""Provenance of the floating-point kernels: recorded in results folders, a mix warned about."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys

import pytest
from test_bench_results import _config, _fake_records

from strol_gym.benchmarks.engine.kernels import ENV_VARS, float_kernels, kernel_label
from strol_gym.benchmarks.engine.results import ResultsDir

OTHER = "openblas=SkylakeX numpy=X86_V4 torch=AVX512 torch-blas=mkl"
"""A label no process here has: an AVX-512 machine's kernels."""


def test_this_process_names_its_openblas_core_and_torch_capability():
    k = float_kernels()
    assert isinstance(k["openblas"], str) and k["openblas"]
    assert k["torch_cpu"] in {"DEFAULT", "NO AVX", "AVX", "AVX2", "AVX512", "ZVECTOR", "VSX"}
    assert k["openblas"] in kernel_label() and k["torch_cpu"] in kernel_label()


@pytest.mark.skipif(platform.machine() != "x86_64", reason="x86 kernel names")
def _kernels_in_a_fresh_process(**variables: str) -> dict:
    """float_kernels() of a new interpreter whose only kernel variables are ``variables``."""
    code = "import json; from strol_gym.benchmarks.engine.kernels import float_kernels as f; "
    code += "print(json.dumps(f()))"
    env = {k: v for k, v in os.environ.items() if k not in ENV_VARS}
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={**env, **variables},
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


def test_kernel_variables_are_honoured_and_recorded():
    k = _kernels_in_a_fresh_process(OPENBLAS_CORETYPE="Prescott", ATEN_CPU_CAPABILITY="default")
    assert k["torch_cpu"] == "DEFAULT"
    assert k["env"] == {"OPENBLAS_CORETYPE": "Prescott", "ATEN_CPU_CAPABILITY": "default"}
    # OpenBLAS reports the kernel it runs: Prescott's is named after its Katmai ancestor. It
    # differs from the one OpenBLAS picks itself, unless this CPU is that old (or this suite
    # runs under OPENBLAS_CORETYPE itself, as .ci/kernels does: the fresh process has none).
    native = _kernels_in_a_fresh_process()
    assert k["openblas"] in {"Prescott", "Katmai"}
    assert native["env"] == {}
    if native["openblas"] not in {"Prescott", "Katmai"}:
        assert k["openblas"] != native["openblas"]


def _units(path):
    return {p.stem: json.loads(p.read_text()) for p in (path / "records").glob("*.json")}


def test_results_folder_records_kernels_per_unit_and_in_meta(tmp_path):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    assert json.loads((tmp_path / "r" / "meta.json").read_text())["kernels"] == float_kernels()
    for u in cfg.units():
        rd.write_unit(u, [{**r, "kernels": kernel_label()} for r in _fake_records(cfg, u)])
    rd.finish_session("t", 1.0, len(cfg.units()), 1)
    units = _units(tmp_path / "r")
    assert {u["kernels"] for u in units.values()} == {kernel_label()}
    assert all("kernels" not in r for u in units.values() for r in u["records"])
    meta = json.loads((tmp_path / "r" / "meta.json").read_text())
    assert meta["record_kernels"] == {kernel_label(): len(cfg.units())}
    assert meta["sessions"][-1]["kernels"] == kernel_label()


def test_resuming_under_other_kernels_warns_naming_which_units(tmp_path, capsys):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    first, *rest = cfg.units()
    rd.write_unit(first, [{**r, "kernels": OTHER} for r in _fake_records(cfg, first)])
    rd.write_unit(rest[0], [{**r, "kernels": kernel_label()} for r in _fake_records(cfg, rest[0])])
    rd.finish_session("t", 1.0, 2, 1)
    capsys.readouterr()
    ResultsDir.open(tmp_path / "r", cfg).finish_session("t", 0.0, 0, 1)
    lines = [ln for ln in capsys.readouterr().err.splitlines() if "kernels" in ln]
    assert len(lines) == 2  # on resume, and again at the end of the session (still mixed)
    line = lines[0]
    assert f"1 unit(s) under [{OTHER}] ({first.key})" in line
    assert f"1 unit(s) under [{kernel_label()}] ({rest[0].key})" in line
    assert f"this process runs [{kernel_label()}]" in line


def test_resuming_under_the_same_kernels_is_silent(tmp_path, capsys):
    cfg = _config()
    rd = ResultsDir.open(tmp_path / "r", cfg)
    unit = cfg.units()[0]
    rd.write_unit(unit, [{**r, "kernels": kernel_label()} for r in _fake_records(cfg, unit)])
    rd.finish_session("t", 1.0, 1, 1)
    ResultsDir.open(tmp_path / "r", cfg)
    assert "kernels" not in capsys.readouterr().err


def test_a_real_run_stamps_its_records_and_a_resume_under_an_edited_kernel_warns(tmp_path, capsys):
    from strol_gym.benchmarks.engine.config import paper_config
    from strol_gym.benchmarks.engine.runner import run_benchmark

    cfg = paper_config(
        ["robot"], runs=2, learners=("gradient", "one"), block=1, reference="gradient"
    )
    cfg = type(cfg)(cfg.experiments[:1], cfg.learners, cfg.reference, cfg.block)
    out = tmp_path / "r"
    run_benchmark(cfg, out, jobs=1, quiet=True)
    units = _units(out)
    assert {u["kernels"] for u in units.values()} == {kernel_label()}
    # As if the first unit had been computed on an AVX-512 machine: a resume there warns.
    key = sorted(units)[0]
    units[key]["kernels"] = OTHER
    (out / "records" / f"{key}.json").write_text(json.dumps(units[key]))
    capsys.readouterr()
    run_benchmark(cfg, out, jobs=1, quiet=True)
    err = capsys.readouterr().err
    assert f"1 unit(s) under [{OTHER}] ({key})" in err


def _stats_csv(folder, rows):
    from strol_gym.benchmarks.engine.results import write_csv

    folder.mkdir(parents=True)
    cols = ("env", "condition", "metric", "learner", "baseline", "p_holm", "mean_diff",
            "wilcoxon_p_holm", "hodges_lehmann", "prob_improvement")  # fmt: skip
    write_csv(folder / "stats.csv", rows, cols)


def test_cross_kernel_lists_every_test_and_names_the_cpu_dependent_verdicts(tmp_path):
    from lab.checks.cross_kernel import compare, tests, tests_table

    base = {"env": "robot", "condition": "noisy-biased", "metric": "regret", "learner": "strol"}
    a = [{**base, "baseline": "e2e", "p_holm": 0.2, "mean_diff": -0.1, "wilcoxon_p_holm": 0.049,
          "hodges_lehmann": -0.01, "prob_improvement": 0.46}]  # fmt: skip
    b = [{**a[0], "wilcoxon_p_holm": 0.101, "prob_improvement": 0.45}]
    _stats_csv(tmp_path / "avx512", a)
    _stats_csv(tmp_path / "avx2", b)
    got = tests(tmp_path / "avx512")
    key = ("robot", "noisy-biased", "regret", "strol", "e2e")
    assert got[("wilcoxon", *key)] == (0.049, "lower") and got[("t", *key)] == (0.2, "n.s.")
    table = tests_table({"avx512": tmp_path / "avx512", "avx2": tmp_path / "avx2"})
    assert len(table) == 2 + 2  # header, rule, one row per test
    wil = next(line for line in table if "| wilcoxon |" in line)
    assert "| 0.049 (lower) | avx2: 0.101 (n.s.) | **depends on the CPU** |" in wil
    assert next(line for line in table if "| t |" in line).endswith("| 0.2 (n.s.) | same | no |")
    (tmp_path / "avx512" / "summary.csv").write_text("env,condition,learner,metric,mean\n")
    (tmp_path / "avx2" / "summary.csv").write_text("env,condition,learner,metric,mean\n")
    _, _, changed, poi = compare(tmp_path / "avx512", tmp_path / "avx2")
    assert changed == ["wilcoxon/robot/noisy-biased/regret/strol/e2e: lower -> n.s."]
    assert poi == pytest.approx(0.01)


def test_cross_kernel_settings():
    from lab.checks.cross_kernel import setting_env

    assert setting_env("native") == {}
    assert setting_env("Prescott:avx2") == {
        "OPENBLAS_CORETYPE": "Prescott",
        "ATEN_CPU_CAPABILITY": "avx2",
    }
    assert setting_env("avx2-cpu")["MKL_ENABLE_INSTRUCTIONS"] == "AVX2"
    with pytest.raises(ValueError, match="--settings"):
        setting_env("Haswell")
