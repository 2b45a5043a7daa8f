"""Helpers the CLI test files share: an in-process call that must fail cleanly."""

from __future__ import annotations

from strol_gym.benchmarks import cli


def cli_error(argv, capsys) -> str:
    """Run the CLI in-process expecting status 2 and one error line without a traceback;
    returns that line (argparse adds a usage block, so only "error:" lines count)."""
    try:
        code = cli.main(argv)
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if "error:" in ln]
    assert len(lines) == 1, err
    return lines[0]
