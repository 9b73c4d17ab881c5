"""Example plug-in surfaces (see catalogs/surfaces.yaml, family ``plugin``).

A plug-in takes x, y arrays [µm] plus the entry's ``params`` as keywords and returns
heights [µm] of the same shape, or (heights, ∂f/∂x, ∂f/∂y).
"""

from __future__ import annotations

import numpy as np


def dimples(
    x: np.ndarray, y: np.ndarray, depth_um: float = 1.0, width_um: float = 80.0, pitch_um: float = 300.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A smooth square array of dimples, f = −d·exp(−(sin²(πx/p) + sin²(πy/p))·p²/(2π²w²)),
    Gaussian-like of width w near each grid point, with its analytic gradient."""
    k = pitch_um**2 / (2.0 * np.pi**2 * width_um**2)
    f = -depth_um * np.exp(-k * (np.sin(np.pi * x / pitch_um) ** 2 + np.sin(np.pi * y / pitch_um) ** 2))
    g = -k * np.pi / pitch_um  # d/dx of −k·sin²(πx/p) is −k·(π/p)·sin(2πx/p)
    return f, f * g * np.sin(2 * np.pi * x / pitch_um), f * g * np.sin(2 * np.pi * y / pitch_um)


def saddle(x: np.ndarray, y: np.ndarray, a_um: float = 2.0, scale_um: float = 1000.0) -> np.ndarray:
    """A saddle f = a·(x² − y²)/L², heights only: ftsweep differentiates it numerically."""
    return a_um * (x * x - y * y) / scale_um**2
