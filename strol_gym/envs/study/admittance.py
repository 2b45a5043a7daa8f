"""StROL-Study-v2's admittance layer: the person's wrench moves the arm's target.

The push (its wrench at the cup frame's origin, world frame) drives an isotropic virtual
mass-spring-damper per axis, M δ̈ + D δ̇ + K δ = w (K the felt stiffness, ``stiffness`` and
``rot_stiffness``; M = K/ω², D = 2ζ√(KM)); the controller tracks the setpoint displaced by δ
(position + δ_p, orientation exp(δ_r) R_sp). The response's direction is therefore the
wrench's whatever the arm's inertia: a force moves the cup along it and a torque turns it about
its axis (a real Panda reads the wrench from its joint torque sensors; here the env knows it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

OMEGA = 6.0
"""The virtual dynamics' natural frequency (rad/s): a held push settles in ~1 s (a 1 s push
reaches 98 % of F/K), and a 60 N push peaks at 0.44 m/s, a 3 N m torque at 0.66 rad/s
(the joints' limits are 2.2-2.6 rad/s)."""
ZETA = 1.0
"""Critically damped: the cup stops where the push leaves it, no overshoot."""
SETTLED = 1e-5
"""Below this (m, rad; per second for the speeds) with no wrench, δ is put to exactly zero
(a 0.01 mm step of the target), and the controller goes back to its unpushed path."""
REST: tuple[float, ...] = (0.0,) * 12
"""δ (6) and δ̇ (6) at rest."""


@dataclass(frozen=True)
class Admittance:
    """The virtual dynamics, discretised exactly for a wrench held over ``dt`` seconds."""

    stiffness: float
    rot_stiffness: float
    dt: float
    omega: float = OMEGA
    zeta: float = ZETA
    _phi: tuple[float, float, float, float, float, float] = field(init=False, repr=False)
    _gain: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        w, z = self.omega, self.zeta
        a = np.array([[0.0, 1.0, 0.0], [-w * w, -2.0 * z * w, 1.0], [0.0, 0.0, 0.0]])
        e = expm(a * self.dt)  # [δ, δ̇, u]: u = w/M held over dt
        phi = (e[0, 0], e[0, 1], e[1, 0], e[1, 1], e[0, 2], e[1, 2])
        object.__setattr__(self, "_phi", tuple(float(x) for x in phi))
        gp, gr = w * w / self.stiffness, w * w / self.rot_stiffness  # 1/M
        object.__setattr__(self, "_gain", (gp, gp, gp, gr, gr, gr))

    def step(self, state: tuple[float, ...], wrench: list[float]) -> tuple[float, ...]:
        """δ and δ̇ after ``dt`` with ``wrench`` (6: N, N m) held; plain floats (it runs every
        physics chunk)."""
        p00, p01, p10, p11, c0, c1 = self._phi
        d, v = state[:6], state[6:]
        u = [a * g for a, g in zip(wrench, self._gain, strict=True)]
        d1 = [p00 * a + p01 * b + c0 * c for a, b, c in zip(d, v, u, strict=True)]
        v1 = [p10 * a + p11 * b + c1 * c for a, b, c in zip(d, v, u, strict=True)]
        if not any(wrench) and max(map(abs, d1 + v1)) < SETTLED:
            return REST
        return (*d1, *v1)

    def coefficients(self) -> tuple[float, ...]:
        """Φ's entries (δ from δ, δ̇, u; δ̇ from δ, δ̇, u) and 1/M per axis, as ``step`` uses
        them (the compiled step's copy of ``step``)."""
        return (*self._phi, *self._gain)

    def mass(self) -> tuple[float, float]:
        """The virtual mass (kg) and rotational inertia (kg m²)."""
        return self.omega**-2 * self.stiffness, self.omega**-2 * self.rot_stiffness


def rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    """exp([r]×): the rotation matrix of the rotation vector r (Rodrigues)."""
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    if angle < 1e-12:
        return np.eye(3)
    x, y, z = rx / angle, ry / angle, rz / angle
    s, c = math.sin(angle), math.cos(angle)
    t = 1.0 - c
    return np.array(
        (
            (c + t * x * x, t * x * y - s * z, t * x * z + s * y),
            (t * x * y + s * z, c + t * y * y, t * y * z - s * x),
            (t * x * z - s * y, t * y * z + s * x, c + t * z * z),
        )
    )
