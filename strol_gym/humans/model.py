"""Renamed: ``strol_gym.humans.interface`` (and ``ModelHuman`` is ``SimulatedHuman``). The old
names warn when used and go in the next release (CHANGELOG.md)."""

from strol_gym.deprecation import moved

_NEW = "strol_gym.humans.interface"
__getattr__ = moved(
    __name__,
    {
        **{
            n: f"{_NEW}:{n}"
            for n in ("DEFAULT_CANDIDATES", "Draws", "Human", "HumanModel", "needs_theta_hat")
        },
        "ModelHuman": f"{_NEW}:SimulatedHuman",
    },
)
