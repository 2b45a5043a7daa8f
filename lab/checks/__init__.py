"""Reproduction and calibration checks: MOF's gate, floating-point kernels, the paper's
departures, fit-human's recovery, candidate learners, the byte-identity fingerprint."""
