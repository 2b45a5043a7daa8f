"""The lab: derivations, calibrations, probes and reproduction checks behind the numbers the docs
quote. Not installed; run from the repository's root with the project's venv, e.g.
``.venv/bin/python -m lab.study.study_reach``. It may import ``strol_gym`` and its benchmarks;
nothing installed imports it."""
