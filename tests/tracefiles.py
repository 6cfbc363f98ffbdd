"""Trace files as users have them, made without gms_comp: the tests' independent source.

A :class:`Motion` is a sine stroke with Coulomb-and-viscous friction, sampled at a
uniform rate, its position read by an encoder; its peak speed and acceleration are known
in closed form (A w, A w^2), so a test knows without the code under test whether a unit
slip takes them out of the range of ball-guided axes. :func:`csv_text` writes it as a user's
logger would: any units, any header names, a byte-order mark, CRLF; the clock helpers
mangle the time stamps (jitter, a change of rate, missing samples, a gap, a repeated
stamp) and say which file row each change lands on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# A logger writes this many significant digits.
DIGITS = 15


@dataclass(frozen=True)
class Motion:
    """x = A sin(2 pi f t), F = Fc tanh(v / v0) + c v + noise, sampled at ``rate_Hz``."""

    rate_Hz: float
    samples: int
    amplitude_m: float
    frequency_Hz: float
    coulomb_N: float
    viscous_Ns_per_m: float = 0.0
    encoder_m: float = 1e-8
    noise_N: float = 0.0
    seed: int = 0

    @property
    def peak_speed_m_s(self) -> float:
        return self.amplitude_m * 2.0 * math.pi * self.frequency_Hz

    @property
    def peak_acceleration_m_s2(self) -> float:
        return self.amplitude_m * (2.0 * math.pi * self.frequency_Hz) ** 2

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Time (s), position (m, encoder counts) and force (N) at the uniform clock."""
        t = np.arange(self.samples) / self.rate_Hz
        w = 2.0 * math.pi * self.frequency_Hz
        x = self.amplitude_m * np.sin(w * t)
        v = self.amplitude_m * w * np.cos(w * t)
        x = np.round(x / self.encoder_m) * self.encoder_m
        rng = np.random.default_rng(self.seed)
        f = self.coulomb_N * np.tanh(v / (0.01 * self.peak_speed_m_s)) + self.viscous_Ns_per_m * v
        return t, x, f + rng.normal(0.0, self.noise_N, t.size)


def csv_text(columns: dict[str, np.ndarray], *, bom: bool = False, crlf: bool = False) -> bytes:
    """A CSV file: the header (names quoted as CSV needs), one row per sample."""
    names = list(columns)
    header = ",".join(
        '"' + n.replace('"', '""') + '"' if any(c in n for c in ',"') else n for n in names
    )
    newline = "\r\n" if crlf else "\n"
    data = np.column_stack([columns[n] for n in names])
    body = newline.join(",".join(f"{v:.{DIGITS}g}" for v in row) for row in data)
    text = header + newline + body + newline
    return (b"\xef\xbb\xbf" if bom else b"") + text.encode()


# --- clock mangling: each returns the new time stamps (and the kept samples) -------------


def jittered(t: np.ndarray, fraction: float, seed: int) -> np.ndarray:
    """Each stamp moved by up to ``fraction``/2 of a step (steps change by <= fraction)."""
    step = float(t[1] - t[0])
    shift = np.random.default_rng(seed).uniform(-0.5, 0.5, t.size) * fraction * step
    return t + shift


def rate_change(samples: int, at: int, keep_every: int) -> np.ndarray:
    """Indices kept when the first ``at`` samples are logged at 1/``keep_every`` of the rate."""
    return np.concatenate([np.arange(0, at, keep_every), np.arange(at, samples)])


def with_gap(t: np.ndarray, at: int, gap_s: float) -> np.ndarray:
    """Stamps from sample ``at`` on shifted by ``gap_s``: file row ``at + 2`` follows the gap."""
    out = t.copy()
    out[at:] += gap_s
    return out


def repeated(t: np.ndarray, at: int) -> np.ndarray:
    """Sample ``at`` stamped like the one before it (file row ``at + 2`` repeats)."""
    out = t.copy()
    out[at] = out[at - 1]
    return out
