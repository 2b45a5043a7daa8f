"""Speed probes that print figures for the docs but no target (the speed scripts that print a
target stay in benchmarks/speed)."""
