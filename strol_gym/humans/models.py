"""Renamed: ``strol_gym.humans.builtin`` (and ``TeacherModel`` is ``NominalModel``). The old
names warn when used and go in the next release (CHANGELOG.md)."""

from strol_gym.deprecation import moved

_NEW = "strol_gym.humans.builtin"
_SAME = ("BoltzmannHuman", "BoltzmannModel", "ChangingHuman", "ChangingModel", "DriverHuman")
__getattr__ = moved(
    __name__,
    {
        **{n: f"{_NEW}:{n}" for n in (*_SAME, "DriverModel", "NominalHuman")},
        "TeacherModel": f"{_NEW}:NominalModel",
    },
)
