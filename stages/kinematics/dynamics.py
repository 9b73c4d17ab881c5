"""Dynamics of the W command (model §1, §6 "Dynamics").

The controller outputs one command per period 1/f_cmd while the spindle turns at n rpm,
K = f_cmd·60/n commands per revolution. The command stream is evaluated over whole
revolutions at a few radii (the outer edge, where surface speed is highest, and inner
radii that may hold other features). Velocity and acceleration are its first and second
differences at the command period (the kinematics stage, :mod:`.kinematics`: [2] eq. 14
on a uniform timestep); the spectrum is the FFT of each revolution with its linear trend removed.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ftsweep.stages.interpolation.spiral_program import SpiralPath
from ftsweep.stages.interpolation.tables import Program, interpolate
from ftsweep.stages.kinematics import axes as kinematics


class Dynamics(NamedTuple):
    """Figures of the W command. Units in the names; frequencies in Hz."""

    stroke_um: float  # range of the table, which bounds every command
    velocity_peak_mm_s: float
    accel_peak_m_s2: float
    accel_rms_m_s2: float
    freq_max_hz: float  # highest significant spectral component
    commands_per_rev: int


def commands_per_revolution(command_rate_hz: float, spindle_rpm: float) -> int:
    """K = f_cmd·60/n (model §1): 20 kHz at 50 rpm gives 24,000."""
    return int(round(command_rate_hz * 60.0 / spindle_rpm))


def revolution_commands(
    layout: Program,
    table: np.ndarray,
    rho_start_um: float,
    feed_um: float,
    k: int,
    n_commands: int | None = None,
    first: int = 0,
) -> np.ndarray:
    """Consecutive commands W [µm] of the spiral, ``k`` per revolution, command n at
    φ_n = 2π·n/k for n = first … first + n_commands − 1 (default one revolution from φ = 0):
    ρ(φ) = ρ_start − F·φ/2π, θ = φ mod 2π (model §1, §3)."""
    count = k if n_commands is None else n_commands
    phi = (first + np.arange(count)) * (2.0 * math.pi / k)
    rho = np.maximum(rho_start_um - feed_um * phi / (2.0 * math.pi), 0.0)
    return interpolate(layout, table, rho, np.mod(phi, 2.0 * math.pi))


def spectrum(w_um: np.ndarray, k: int, spindle_rpm: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum of one revolution of commands, the feed's drift removed.

    ``w_um`` holds the revolution's ``k`` commands and, where given, the next one (the first
    of the next revolution): the drift is then the change over the revolution, ``(w[k] −
    w[0])·t/k``, which makes the revolution periodic, so its spectrum holds no leakage from
    the jump a periodic extension would have (a straight 1/f line on log axes); with ``k``
    commands only, the least-squares line is removed. Returns frequencies [Hz] (multiples of
    the spindle frequency n/60) and amplitudes [µm] of each harmonic, DC excluded.
    """
    t = np.arange(k)
    if len(w_um) > k:
        w = np.asarray(w_um[: k + 1], dtype=np.float64)
        detrended = w[:k] - (w[k] - w[0]) * t / k
    else:
        w = np.asarray(w_um[:k], dtype=np.float64)
        detrended = w - np.polyval(np.polyfit(t, w, 1), t)
    amp = 2.0 * np.abs(np.fft.rfft(detrended)) / k
    freq = np.arange(amp.size) * (spindle_rpm / 60.0)
    return freq[1:], amp[1:]


def highest_significant_frequency(freq: np.ndarray, amp: np.ndarray, floor_um: float) -> float:
    """Highest frequency [Hz] whose amplitude [µm] reaches ``floor_um`` (0 if none does)."""
    keep = np.flatnonzero(amp >= floor_um)
    return float(freq[keep[-1]]) if keep.size else 0.0


# the fractions of the start radius whose revolutions the dynamics are judged on (model §6)
ANALYSED_RADII = (1.0, 0.75, 0.5, 0.25)


def analysed_revolution(
    layout: Program, table: np.ndarray, rho0_um: float, feed_um: float, k: int, fraction: float
) -> np.ndarray:
    """The ``k + 2`` commands [µm] of the revolution :func:`analyse` reads at ``fraction`` of the
    start radius ``rho0_um``: one revolution plus its neighbouring commands, so that its
    differences cover all of it (its spectrum is that of ``[1 : k + 2]``: the revolution and the
    next revolution's first command, :func:`spectrum`)."""
    start = fraction * rho0_um
    if isinstance(layout, SpiralPath):
        # a path program is only defined on its own spiral: start on its revolution nearest,
        # one revolution in at least, so that the command before the first (first=-1) lies
        # on the program and not a revolution on, across the spiral's start
        start = rho0_um - feed_um * max(round((rho0_um - start) / feed_um), 1)
    return revolution_commands(layout, table, start, feed_um, k, k + 2, first=-1)


def significance_floor(spectra: list[tuple[np.ndarray, np.ndarray]], threshold: float) -> float:
    """The amplitude [µm] from which a component is significant: ``threshold`` of the dominant
    component over every analysed revolution's spectrum, and at least 1 pm."""
    dominant = max(float(amp.max()) for _, amp in spectra)
    return max(threshold * dominant, 1e-6)


def analyse(
    layout: Program,
    table: np.ndarray,
    rho0_um: float,
    feed_um: float,
    spindle_rpm: float,
    command_rate_hz: float,
    threshold: float = 0.01,
    radii_fraction: tuple[float, ...] = ANALYSED_RADII,
) -> Dynamics:
    """Stroke, peak velocity, peak and RMS acceleration and highest significant frequency of
    the W command at the spindle speed (model §6).

    Parameters
    ----------
    layout, table : the control table [µm] the controller holds.
    rho0_um : start radius of the spiral [µm]; revolutions start at ``radii_fraction``·ρ0.
    feed_um : feed per revolution [µm/rev].
    spindle_rpm : spindle speed [rev/min].
    command_rate_hz : controller command rate [Hz].
    threshold : a spectral component is significant when its amplitude is at least this
        fraction of the dominant component over all analysed revolutions (and at least
        1 pm, so a constant command has no significant content).
    """
    k = commands_per_revolution(command_rate_hz, spindle_rpm)
    dt = 1.0 / command_rate_hz
    v_peak = a_peak = a_sq = 0.0
    n_acc = 0
    spectra = []
    for frac in radii_fraction:
        w = analysed_revolution(layout, table, rho0_um, feed_um, k, frac)
        m = kinematics.over_steps(w[:, None] * 1e-6, np.full(w.size - 1, dt))
        v = m.velocity[:, 0] * 1e3  # m/s → mm/s
        a = m.accel[1:-1, 0]
        v_peak = max(v_peak, float(np.max(np.abs(v))))
        a_peak = max(a_peak, float(np.max(np.abs(a))))
        a_sq += float(np.sum(a * a))
        n_acc += a.size
        spectra.append(spectrum(w[1 : k + 2], k, spindle_rpm))
    floor = significance_floor(spectra, threshold)
    f_max = max(highest_significant_frequency(freq, amp, floor) for freq, amp in spectra)
    return Dynamics(
        stroke_um=float(np.max(table) - np.min(table)),
        velocity_peak_mm_s=v_peak,
        accel_peak_m_s2=a_peak,
        accel_rms_m_s2=math.sqrt(a_sq / max(n_acc, 1)),
        freq_max_hz=f_max,
        commands_per_rev=k,
    )


def feasibility(
    dyn: Dynamics,
    travel_um: float,
    peak_accel_m_s2: float,
    continuous_accel_m_s2: float,
    bandwidth_hz: float,
) -> tuple[bool, str]:
    """Whether the W motion fits the servo: travel, peak and continuous (RMS) acceleration,
    closed-loop bandwidth. Returns (feasible, reason naming every limit exceeded)."""
    reasons = []
    if dyn.stroke_um > travel_um:
        reasons.append(f"stroke {dyn.stroke_um:.4g} µm > travel {travel_um:.4g} µm")
    if dyn.accel_peak_m_s2 > peak_accel_m_s2:
        reasons.append(f"peak acceleration {dyn.accel_peak_m_s2:.4g} m/s² > {peak_accel_m_s2:.4g} m/s²")
    if dyn.accel_rms_m_s2 > continuous_accel_m_s2:
        reasons.append(
            f"RMS acceleration {dyn.accel_rms_m_s2:.4g} m/s² > continuous {continuous_accel_m_s2:.4g} m/s²"
        )
    if dyn.freq_max_hz > bandwidth_hz:
        reasons.append(f"significant content at {dyn.freq_max_hz:.4g} Hz > bandwidth {bandwidth_hz:.4g} Hz")
    return (not reasons, "; ".join(reasons))
