"""Scenes and closed forms that several test modules share: a helper module, so that a test module need not import
another (whose tests would then be reachable from two modules)."""

from __future__ import annotations

import numpy as np


def oscillator_exact(t: np.ndarray, amplitude: float, omega: float, zeta: float) -> np.ndarray:
    """Displacement from equilibrium of m x'' + c x' + k x = 0 with x(0) = amplitude, x'(0) = 0."""
    if zeta < 1:
        omega_d = omega * np.sqrt(1 - zeta**2)
        return np.exp(-zeta * omega * t) * amplitude * (np.cos(omega_d * t)
                                                        + zeta * omega / omega_d * np.sin(omega_d * t))
    if zeta == 1:
        return amplitude * (1 + omega * t) * np.exp(-omega * t)
    root = np.sqrt(zeta**2 - 1)
    r1, r2 = -omega * (zeta - root), -omega * (zeta + root)
    c1 = amplitude * r2 / (r2 - r1)
    c2 = amplitude - c1
    return c1 * np.exp(r1 * t) + c2 * np.exp(r2 * t)


def oscillator_scene(zeta: float, *, method: str = "DOP853", dt: float | None = None, duration: float = 3.0,
                     fps: int = 20) -> str:
    """A 2 kg mass on a horizontal spring (k = 50 N/m, rest 1 m) to an anchor, pulled 0.2 m and released."""
    mass, stiffness = 2.0, 50.0
    damping = float(2 * zeta * np.sqrt(stiffness * mass))
    solver = f"{{method: {method}, rtol: 1.0e-11, atol: 1.0e-13}}" if dt is None else f"{{method: {method}, dt: {dt}}}"
    return f"""
        duration: {duration}
        fps: {fps}
        solver: {solver}
        anchors: [{{name: wall, position: [0, 0, 0]}}]
        bodies: [{{name: mass, mass: {mass}, position: [1.2, 0, 0]}}]
        springs: [{{between: [wall, mass], stiffness: {stiffness}, damping: {damping!r}, rest_length: 1.0}}]
    """


def cloth(solver: str, *, stiffness: float = 400.0, damping: float = 0.05, extra: str = "", size: str = "[8, 6]",
          pin: str = "[{corners: [top-left, top-right]}]", duration: float = 2.0, fps: int = 30) -> str:
    """A 0.8 × 0.6 m cloth of 0.2 kg/m² hanging from two corners, with all three spring families."""
    return f"""
        duration: {duration}
        fps: {fps}
        solver: {solver}
        bodies:
          - name: sheet
            type: cloth
            grid: {{size: [0.8, 0.6], resolution: {size}}}
            position: [0, 1, 0]
            density: 0.2
            structural: {{stiffness: {stiffness}, damping: {damping}}}
            shear: {{stiffness: {stiffness / 4}, damping: {damping / 4}}}
            bend: {{stiffness: {stiffness / 40}, damping: {damping / 40}}}
            pin: {pin}
        fields: [{{type: gravity}}]
        {extra}
    """


def on_screen_extent(placement, aspect: float, points: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Normalised screen coordinates (…, 2) of spheres at ``points`` (…, 3) [m] by a pinhole camera, grown by each
    sphere's projected radius: |x|, |y| ≤ 1 is inside the frame."""
    forward = placement.focal_point - placement.position
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, placement.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tangent = np.tan(np.radians(placement.view_angle) / 2)
    relative = points - placement.position
    depth = relative @ forward
    assert (depth > 0).all(), "a body behind the camera"
    grow = radius / (depth * tangent)
    x = np.abs(relative @ right) / (depth * tangent * aspect) + grow / aspect
    y = np.abs(relative @ up) / (depth * tangent) + grow
    return np.stack([x, y], axis=-1)
