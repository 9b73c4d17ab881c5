"""Motion checked by finite differences in plain numpy, independent of the kinematics stage, and
the axes of an exported Fresnel program read back as printed."""

from __future__ import annotations

import numpy as np


def fd_peaks(q: np.ndarray, steps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest |velocity| over the steps and |acceleration| over the interior points, per axis:
    v = Δq/T, a = 2(v_i − v_{i−1})/(T_{i−1} + T_i) ([2] eq. 14), plain numpy."""
    v = np.diff(q, axis=0) / steps[:, None]
    a = 2.0 * (v[1:] - v[:-1]) / (steps[:-1] + steps[1:])[:, None]
    return np.abs(v).max(axis=0), (np.abs(a).max(axis=0) if a.size else np.zeros(q.shape[1]))


def within(q: np.ndarray, steps: np.ndarray, velocity: np.ndarray, accel: np.ndarray, rel: float) -> bool:
    v, a = fd_peaks(q, steps)
    return bool(np.all(v <= velocity * (1.0 + rel)) and np.all(a <= accel * (1.0 + rel)))


def exported_axes(path) -> tuple[np.ndarray, np.ndarray]:
    """The positions (P, 4) SI (C rad, X Y Z m) and steps [s] of an exported Fresnel program's
    ``t C X Y Z`` lines, as printed."""
    lines = path.read_text().splitlines()
    data = np.loadtxt(path, comments="#", skiprows=lines.index("t_s C_deg X_mm Y_mm Z_mm") + 1)
    return np.column_stack([np.radians(data[:, 1]), data[:, 2:] * 1e-3]), np.diff(data[:, 0])
