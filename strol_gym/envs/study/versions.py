"""The versions of StROL-Study as option sets of one env class (``strol_gym.envs.study.env``).

Each version is a frozen :class:`StudyVersion`, said once here: its number, and what it changes
as fields read by the one ``StudyEnv`` (no version subclasses another to override its
internals). Everything else that names a version derives from it: its env id
(``StROL-Study-vN``), its registration and env class (``env_class``), its Tasks
(``tasks``: ``strol_gym.tasks.study.STUDY_TASK_SETS``, their ``task_id`` the key of their
shipped ĝ and ``weights_stem`` the files' names) and the benchmark's presets and
``--env-version`` choices. A new version is a new ``StudyVersion`` in ``VERSIONS`` (its new
behaviour a new field whose default keeps the others as they are), its Tasks and an env class
that names it (``version = V3``); ``tests/test_study_versions.py`` checks that every name
agrees.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from strol_gym.envs.study.geometry import REACH_ANGLE, REACH_HIGH, REACH_LOW
from strol_gym.tasks.study import STUDY_TASK_SETS, StudyTask, study_env_id

PARTICIPANTS = ("observer", "oracle")
"""``observer``: ``Participant``, who judges the cup's motion under its θ* (held out: no shipped
ĝ was trained on its corrections); ``oracle``: v0's ``SimulatedUser`` with the human model
(``human``, default eq. M6, the training human), satisfied by the plan's regret."""
PARTICIPANTS_V2 = ("fitted", *PARTICIPANTS)
"""v2's: ``fitted`` (default), a person drawn from the population fitted to the authors' twelve
participants (``population``, ``participant.FittedParticipant``), then v1's two."""
HOLD_OFF = 0.4
"""s, v2's hold-off: a push whose force comes back within 0.4 s is the same push. Shorter would
cut real pushes: ``strol-bench interact`` hands the env the viewer's perturbation, updated at
least every 5th control step (0.25 s), and between updates the force sags as the arm moves
towards the mouse (an xdotool drag sagged to 7 N for 0.25 s between 17 N and 29 N); a person
who lets go to regrip takes a reaction time (0.2-0.25 s) and the hand's move. Longer would
merge deliberate pushes and delay the learner's update after each release by as much; the
arm yields through it, so u_H hardly depends on it (docs/study.md)."""
REST_TRUST = 0.01
"""m: beyond this lag at a correction's start, u_H is measured from the cup's pose (v0's way)."""


@dataclass(frozen=True, eq=False)
class StudyVersion:
    """The options of one StROL-Study version (docs/study.md measures each change)."""

    number: int
    """N in ``StROL-Study-vN``: the version's every name derives from it."""
    controller: str = "v0"
    """The impedance law (``strol_gym.envs.study.controller``): "v0" or "v1" (integral,
    Λ-based damping, feedforward, null-space home pull, joint speed limits)."""
    rest_pose: bool = False
    """u_H from the held setpoint (where the held arm would rest, within ``REST_TRUST`` of the
    cup) instead of the cup's pose when the push begins."""
    reach: tuple[np.ndarray, np.ndarray, float] | None = None
    """The box executed plans are clipped into (``geometry.within_reach``); None: the Task's."""
    reflex: bool = False
    """The Cartesian force reflex and brakes, ``pause``, and info ``reflex``, ``braked``,
    ``reflexes``, ``lag``, ``gave_up``; arguments ``reflex_force``, ``reflex_torque``,
    ``reflex_recover``."""
    participants: tuple[str, ...] = ()
    """The simulated people the ``participant`` argument chooses from (the first is the
    default); empty: no such argument, the regret-judging ``SimulatedUser``."""
    counterfactual: bool = False
    """u_H = the pushed pose − the pose the held arm reaches without the push over the same
    interval (the simulation copied when the push begins, ``mj_copyData``, and run again
    without it); ``info["correction_state"]`` is that unpushed pose."""
    joint_brake: bool = False
    """The joint speed limits at every physics step through the torques (saturating against
    the motion from 0.9x the limit) instead of clipping ``qvel`` after a chunk of steps."""
    joint_room: bool = False
    """The joints' position limits kept: the null space's posture spring holds the twisting
    joints off theirs (``controller.LIMIT_BAND``), and a push that drives one of them to its
    limit trips the reflex (``controller.POSITION_REFLEX``), as the Panda's own controller
    stops. The reflex is checked where ``joint_brake`` steps the physics one step at a time."""
    contact_info: bool = False
    """``info["contact"]``: the cup touched the pitcher, the plate (or its riser) or the table
    during the step; ``info["contacts"]`` counts such steps."""
    stiffness: float = 400.0
    """The default Cartesian stiffness (N/m; the ``stiffness`` argument overrides it)."""
    rot_stiffness: float = 30.0
    """The default rotational stiffness (N m/rad; the ``rot_stiffness`` argument overrides it)."""
    hull_return: bool = False
    """The way home goes around the objects' hulls (``StudyTaskV2.around_hulls``), not through
    them in a straight line."""
    numbered_tasks: int | None = None
    """The version whose Tasks ``task=1, 2, 3`` build (None: this version's own, ``tasks``).
    v1: 0, v0's Tasks and so v0's ĝ, as v1 shipped; v1's own by name (``study-task1-v1``)."""
    admittance: bool = False
    """The person's wrench moves the controller's target through an isotropic virtual
    mass-spring-damper (``strol_gym.envs.study.admittance``; its stiffness the ``stiffness`` and
    ``rot_stiffness`` arguments) and the tracking law cancels that wrench (known, as a Panda's
    joint torque sensors measure it): the cup yields along the force and about the torque's
    axis whatever the arm's inertia."""
    track_bandwidth: float | None = None
    """The tracking law's gains as a bandwidth (rad/s): stiffness ω² Λ and damping 2ωΛ, Λ
    the cup's task-space inertia (every direction, turns included, tracks alike: v1's scalar
    10 N m/rad left the heavy turns 30x softer than the light ones); None: v1's gains
    (``stiffness``, ``rot_stiffness``, damping critical for Λ)."""
    integral_gain: tuple[float, float] | None = None
    """The integral's gains (1/s) as multiples of the stiffness; None: ``controller.K_INTEGRAL``."""
    torque_reflex: float | None = None
    """The reflex also trips when the person's wrench loads a joint beyond this share of its
    torque limit (``StudyEnv._overloads``); None: force and torque thresholds only. v2: 0.9,
    the motor keeps a tenth of its torque to hold the arm (at 1.0 a push loading the wrist to
    0.99 of its limit saturated it and the cup turned 107° off the torque's axis)."""
    integral_max: tuple[float, float] | None = None
    """Bounds of the integral wrench per axis (N, N m); None: ``controller.INTEGRAL_MAX``."""
    hold_off: float | None = None
    """None: a correction ends at the first step the felt force is at or below the threshold,
    the setpoint held throughout (the published rule). A number: the default hold-off (s; the
    ``hold_off`` argument, ``segment.HOLD_OFF_RANGE``): a correction ends once the force has
    stayed at or below the threshold that long (``segment.PushSegmenter``), and while it
    lasts the arm yields: below the threshold the setpoint follows the cup, so the arm stays
    where the person left it instead of springing back through the hold-off."""

    @property
    def name(self) -> str:
        """``vN``: the version's name on the benchmark's command line (``--env-version``)."""
        return f"v{self.number}"

    @property
    def env_id(self) -> str:
        """``StROL-Study-vN``, its registered id."""
        return study_env_id(self.number)

    @property
    def env_class(self) -> str:
        """The name of the class in ``strol_gym.envs.study.env`` that registers it:
        ``StudyEnv`` (v0), ``StudyEnvVN``."""
        return f"StudyEnvV{self.number}" if self.number else "StudyEnv"

    @property
    def tasks(self) -> Mapping[int, type[StudyTask]]:
        """Its Task classes by number (``STUDY_TASK_SETS``): their ``task_id`` keys their ĝ."""
        return STUDY_TASK_SETS[self.number]

    @property
    def numbered(self) -> Mapping[int, type[StudyTask]]:
        """The Task classes ``task=1, 2, 3`` build (``numbered_tasks``)."""
        return STUDY_TASK_SETS[self.number if self.numbered_tasks is None else self.numbered_tasks]


V0 = StudyVersion(0)
"""As published: kept unchanged for the published results."""
V1 = StudyVersion(
    1,
    controller="v1",
    rest_pose=True,
    reach=(REACH_LOW, REACH_HIGH, REACH_ANGLE),
    reflex=True,
    participants=PARTICIPANTS,
    numbered_tasks=0,
)
"""u_H = the person's push, tracking, the reachable box, the Panda's limits, the reflex."""
V2 = StudyVersion(
    2,
    controller="v1",
    counterfactual=True,
    joint_brake=True,
    joint_room=True,
    contact_info=True,
    stiffness=300.0,
    rot_stiffness=10.0,
    reflex=True,
    participants=PARTICIPANTS_V2,
    hull_return=True,
    admittance=True,
    track_bandwidth=14.0,
    integral_gain=(4.0, 4.0),
    integral_max=(20.0, 3.0),
    torque_reflex=0.9,
    hold_off=HOLD_OFF,
)
"""u_H by counterfactual, the joint limits at every physics step, the Task's reachable set and
hulls in its planner (no executed box: ``reach`` None), a softer arm, ``info["contact"]``, one
push one correction (the hold-off)."""
VERSIONS = {v.name: v for v in (V0, V1, V2)}
"""Every StROL-Study version by name, oldest first: the registrations, the Task registry's
study Tasks and the benchmark's ``--env-version`` follow it."""
LATEST = max(VERSIONS.values(), key=lambda v: v.number)
"""The version to use (gymnasium warns on making an older one)."""


def version_of(env_id: str) -> StudyVersion:
    """The version registered as ``env_id``; ValueError naming the study's ids otherwise."""
    for v in VERSIONS.values():
        if v.env_id == env_id:
            return v
    ids = [v.env_id for v in VERSIONS.values()]
    raise ValueError(f"env_id must be one of {ids}, got {env_id!r}")
