"""The versions of StROL-Study as option sets of one env class (``strol_gym.envs.study.env``).

Each version is a frozen :class:`StudyVersion`: what it changes is a field, read by the one
``StudyEnv``; no version subclasses another to override its internals. A new version (say
``StROL-Study-v2``) is a new ``StudyVersion`` (its new behaviour a new field whose default
keeps v0 and v1 as they are), a class that names it (``version = V2``) and a registration.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from strol_gym.envs.study.geometry import REACH_ANGLE, REACH_HIGH, REACH_LOW
from strol_gym.tasks.study import STUDY_TASKS_V2, StudyTask

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

    name: str
    env_id: str
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
    tasks: Mapping[int, type[StudyTask]] | None = None
    """The Task classes ``task=1, 2, 3`` build (None: ``STUDY_TASKS``, the published ones)."""
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


V0 = StudyVersion("v0", "StROL-Study-v0")
"""As published: kept unchanged for the published results."""
V1 = StudyVersion(
    "v1",
    "StROL-Study-v1",
    controller="v1",
    rest_pose=True,
    reach=(REACH_LOW, REACH_HIGH, REACH_ANGLE),
    reflex=True,
    participants=PARTICIPANTS,
)
"""u_H = the person's push, tracking, the reachable box, the Panda's limits, the reflex."""
V2 = StudyVersion(
    "v2",
    "StROL-Study-v2",
    controller="v1",
    counterfactual=True,
    joint_brake=True,
    joint_room=True,
    contact_info=True,
    stiffness=300.0,
    rot_stiffness=10.0,
    reflex=True,
    participants=PARTICIPANTS_V2,
    tasks=STUDY_TASKS_V2,
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
