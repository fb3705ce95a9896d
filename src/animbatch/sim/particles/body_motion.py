"""Where the scene's rigid bodies are between frames, for emitters that move with them.

The bodies are simulated first and sampled at the frame times; an emitter attached to a body needs the body's pose
at every birth instant. Between frames the centre of mass follows the cubic Hermite curve through the frame
positions and velocities (exact for constant acceleration), the velocity and the angular velocity are interpolated
linearly, and the orientation turns along the shortest arc (slerp) between the frame quaternions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch import quaternion


@dataclass(frozen=True)
class BodyPose:
    """Poses of one body at K instants: centre of mass [m] (K, 3), rotation body-to-world (K, 3, 3), velocity [m/s]
    (K, 3), angular velocity [rad/s] (K, 3)."""

    centre: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray


def slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Unit quaternions (K, 4) a fraction ``s`` (K,) of the way from q0 to q1 (K, 4), along the shorter arc."""
    dot = np.einsum("ij,ij->i", q0, q1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot)
    angle = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(angle)
    close = sin < 1e-9
    w0 = np.where(close, 1.0 - s, np.sin((1.0 - s) * angle) / np.where(close, 1.0, sin))
    w1 = np.where(close, s, np.sin(s * angle) / np.where(close, 1.0, sin))
    return quaternion.normalized(w0[:, None] * q0 + w1[:, None] * q1)


@dataclass(frozen=True, eq=False)
class BodyMotion:
    """The sampled motion of bodies: ``times`` (F,) [s]; per frame and body ``positions`` (F, P, 3) [m] of centres
    of mass, ``velocities`` (F, P, 3), ``orientations`` (F, P, 4), ``angular_velocities`` (F, P, 3)."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    orientations: np.ndarray
    angular_velocities: np.ndarray

    def pose(self, body: int, t: np.ndarray) -> BodyPose:
        """The pose of body ``body`` (its index in the trajectory) at times ``t`` (K,) [s]."""
        t = np.clip(np.asarray(t, float), self.times[0], self.times[-1])
        if len(self.times) == 1:
            k = np.zeros(len(t), int)
            s = np.zeros(len(t))
            h = 1.0
        else:
            k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
            h = self.times[k + 1] - self.times[k]
            s = (t - self.times[k]) / h
        nxt = np.minimum(k + 1, len(self.times) - 1)
        x0, x1 = self.positions[k, body], self.positions[nxt, body]
        v0, v1 = self.velocities[k, body], self.velocities[nxt, body]
        s2, s3 = s * s, s * s * s
        hh = np.reshape(h, (-1, 1)) if np.ndim(h) else h
        centre = ((2 * s3 - 3 * s2 + 1)[:, None] * x0 + (s3 - 2 * s2 + s)[:, None] * hh * v0
                  + (-2 * s3 + 3 * s2)[:, None] * x1 + (s3 - s2)[:, None] * hh * v1)
        velocity = (1 - s)[:, None] * v0 + s[:, None] * v1
        omega = (1 - s)[:, None] * self.angular_velocities[k, body] + s[:, None] * self.angular_velocities[nxt, body]
        rotation = quaternion.to_matrix(slerp(self.orientations[k, body], self.orientations[nxt, body], s))
        return BodyPose(centre, rotation, velocity, omega)
