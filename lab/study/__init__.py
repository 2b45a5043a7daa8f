"""The user study: the reachable-set derivation, push and tracking probes, calibrations,
seed-set sweeps and checks against the authors' data."""
