"""StROL-Study-v0, -v1 and -v2: the paper's user study, a person pushing a compliant Panda arm
that carries a cup, in MuJoCo.

- ``env``: ``StudyEnv``, one class for every version; ``StudyEnv`` is v0 (as published),
  ``StudyEnvV1`` names v1, ``StudyEnvV2`` v2.
- ``versions``: each version said once, a frozen ``StudyVersion`` of options (``V0``, ``V1``,
  ``V2``, ``VERSIONS``) from which its env id, env class, Tasks and ĝ names derive; a new
  version is a new option set.
- ``controller``: the impedance controllers (v0's, v1's); ``geometry``: pose helpers and the
  reachable box; ``scene``: the MuJoCo scene.
- ``people``: the interface of whoever pushes (``Pusher``); ``user`` (the regret-judging
  simulated user), ``participant`` (the simulated participant who judges what it sees, and
  ``FittedParticipant``, v2's default); ``population`` (the population fitted to the authors'
  twelve participants, read from the shipped ``participant_fit.json``); ``persons``: those
  people by the names ``person=`` gives them (``"fitted"``, ``"observer"``, ``"oracle"``), what
  each takes and builds (``StudyPerson``, the env's ``person`` slot).
- ``metrics``: the study's metrics the authors' way.

Names load their module on first use.
"""

from strol_gym.lazy import exports

_ENV = "strol_gym.envs.study.env"
__all__ = ["V0", "V1", "V2", "StudyEnv", "StudyEnvV1", "StudyEnvV2", "StudyVersion"]
__getattr__ = exports(
    __name__,
    {
        "StudyEnv": _ENV,
        "StudyEnvV1": _ENV,
        "StudyEnvV2": _ENV,
        **dict.fromkeys(("V0", "V1", "V2", "StudyVersion"), "strol_gym.envs.study.versions"),
    },
)
