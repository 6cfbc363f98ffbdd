"""Units of a trace checked by physics: what no ball-guided linear axis does is refused.

A column in the wrong unit (position in mm, force in kN) would only give a wrong
diagnosis, so the motion and the force of a trace on its uniform clock are compared with
what a ball-guided linear axis can do: its stroke, its speed and acceleration (read from
the position over a few ms, so that encoder steps and noise do not count), its position
resolution against its stroke, the size of its force. A value out of range is refused
with the units it looks like (the ones that bring every figure into range) and the
``--map`` that scales the column; a stroke too short to show friction is refused with
what to record instead. Each bound is a named constant with its reason (docs/limits.md).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.errors import TraceError
from gms_comp.measured.trace_map import scaled

#: Longest stroke of a trace's position, m: ball-guided axes travel a few metres at most.
MAX_STROKE_M = 5.0
#: Shortest stroke, m: ball guides' contacts break away over 1-50 um (presliding); a
#: shorter motion never leaves the contacts' elastic spring, and no catalogue effect
#: (all act while sliding or at break-away) can be told from it.
MIN_STROKE_M = 1e-6
#: Shortest stroke in position steps (the encoder's count, or the position noise): over
#: fewer, presliding and break-away are a staircase of a few counts, not a curve.
MIN_STROKE_STEPS = 20.0
#: Top speed from the position (over ``SPEED_WINDOW_S``), m/s: ball guides are rated to
#: 5-10 m/s.
MAX_SPEED_M_S = 10.0
#: Top acceleration from the position (over ``ACCELERATION_WINDOW_S``), m/s^2: ball guides
#: are rated to about 500 m/s^2 (50 g), linear motors rarely reach 100 g.
MAX_ACCELERATION_M_S2 = 1000.0
#: Largest force, N: more than any linear motor or friction device exerts; looks like mN.
MAX_FORCE_N = 1e6
#: Smallest peak of a non-zero force over the whole trace, N: the friction of the smallest
#: ball guides (miniature rails) is about 0.1 N; a force that never reaches a quarter of it
#: looks like kN.
MIN_FORCE_N = 0.025

# Speed and acceleration are read from the position over these windows (at least one
# sample step): long enough that an encoder count or the noise of a sample does not count
# (a 1 um count over 5 ms is 0.04 m/s^2), short against any move of a linear axis.
SPEED_WINDOW_S = 2e-3
ACCELERATION_WINDOW_S = 5e-3

# Units a length column is found in, most common first, with their factor to metres.
_LENGTH_UNITS = (("mm", 1e-3), ("um", 1e-6), ("cm", 1e-2), ("nm", 1e-9))
_SPEED_UNITS = (("mm/s", 1e-3), ("um/s", 1e-6), ("cm/s", 1e-2))
_FORCE_UNITS = (("kN", 1e3), ("mN", 1e-3))


def check_position(
    position_m: FloatArray, sample_time_s: float, source: str, expr: str = "position_m"
) -> None:
    """Refuse a position whose stroke, speed or acceleration no ball-guided axis has, or
    whose stroke is too short to show friction.

    Raises
    ------
    TraceError
        Naming the column, the figure, the unit it looks like and the ``--map`` to use.
    """
    stroke = float(np.ptp(position_m))
    field = "column position_m"
    if stroke == 0.0:
        raise TraceError(source, field, "no motion (the position never changes)")
    resolution = position_resolution(position_m)
    if stroke < MIN_STROKE_M or stroke < MIN_STROKE_STEPS * resolution:
        raise TraceError(source, field, _too_short(stroke, resolution, expr))
    speed = peak_speed(position_m, sample_time_s)
    acceleration = peak_acceleration(position_m, sample_time_s)
    figures = {
        "stroke": (stroke, MAX_STROKE_M, "m"),
        "speed": (speed, MAX_SPEED_M_S, "m/s"),
        "acceleration": (acceleration, MAX_ACCELERATION_M_S2, "m/s^2"),
    }
    over = [(k, v, cap, u) for k, (v, cap, u) in figures.items() if v > cap]
    if not over:
        return
    name, value, cap, unit = over[0]

    def fits(factor: float) -> bool:
        small = all(v * factor <= c for v, c, _ in figures.values())
        return small and stroke * factor >= MIN_STROKE_M

    raise TraceError(
        source, field,
        f"its {name} reaches {value:.4g} {unit}, more than the {cap:g} {unit} of any "
        f"ball-guided axis: {_looks_like(_LENGTH_UNITS, fits, 'position_m', expr, 'metres')}",
    )  # fmt: skip


def check_velocity(velocity_m_s: FloatArray, source: str, expr: str = "velocity_m_s") -> None:
    """Refuse a velocity column faster than any ball-guided axis."""
    speed = float(np.max(np.abs(velocity_m_s)))
    if speed <= MAX_SPEED_M_S:
        return
    raise TraceError(
        source, "column velocity_m_s",
        f"reaches {speed:.4g} m/s, more than the {MAX_SPEED_M_S:g} m/s of any ball-guided "
        "axis: " + _looks_like(
            _SPEED_UNITS, lambda f: speed * f <= MAX_SPEED_M_S, "velocity_m_s", expr, "m/s"
        ),
    )  # fmt: skip


def check_force(force_N: FloatArray, source: str, expr: str = "force_N") -> None:
    """Refuse a force larger than any axis exerts or smaller than any guide's friction (a
    force of zero throughout is left to the diagnosis, which says why it cannot use it)."""
    top = float(np.max(np.abs(force_N)))
    if top > MAX_FORCE_N:
        seen = f"reaches {top:.4g} N, more than the {MAX_FORCE_N:g} N of any linear axis"
    elif 0.0 < top < MIN_FORCE_N:
        seen = (
            f"never exceeds {top:.3g} N, less than the {MIN_FORCE_N:g} N the friction of the "
            "smallest ball guide reaches"
        )
    else:
        return

    def fits(factor: float) -> bool:
        return MIN_FORCE_N <= top * factor <= MAX_FORCE_N

    raise TraceError(
        source, "column force_N",
        f"{seen}: {_looks_like(_FORCE_UNITS, fits, 'force_N', expr, 'newtons')}",
    )  # fmt: skip


def position_resolution(position_m: FloatArray) -> float:
    """The position's smallest meaningful step, m: its encoder count (the 5th percentile
    of the non-zero changes between samples) or its noise, whichever is larger. The noise
    is read from the median third difference (white noise gives sqrt(20) x its RMS; a
    motion sampled n times a period only (2 pi / n)^3 of its amplitude)."""
    x = np.asarray(position_m, dtype=float)
    changes = np.abs(np.diff(x))
    changes = changes[changes > 0.0]
    count = float(np.percentile(changes, 5)) if changes.size else 0.0
    if x.size < 4:
        return count
    noise = float(np.median(np.abs(np.diff(x, 3)))) / 0.6745 / np.sqrt(20.0)
    return max(count, noise)


def peak_speed(position_m: FloatArray, sample_time_s: float) -> float:
    """Top speed, m/s, from the position's change over ``SPEED_WINDOW_S``."""
    w = _window(SPEED_WINDOW_S, sample_time_s, position_m.size - 1)
    return float(np.max(np.abs(position_m[w:] - position_m[:-w]))) / (w * sample_time_s)


def peak_acceleration(position_m: FloatArray, sample_time_s: float) -> float:
    """Top acceleration, m/s^2, from the position's second difference over
    ``ACCELERATION_WINDOW_S``."""
    x = position_m
    w = _window(ACCELERATION_WINDOW_S, sample_time_s, (x.size - 1) // 2)
    if w == 0:
        return 0.0
    second = x[2 * w :] - 2.0 * x[w:-w] + x[: -2 * w]
    return float(np.max(np.abs(second))) / (w * sample_time_s) ** 2


def _window(window_s: float, sample_time_s: float, most: int) -> int:
    return min(max(1, round(window_s / sample_time_s)), max(most, 0))


def _too_short(stroke: float, resolution: float, expr: str) -> str:
    steps = stroke / resolution if resolution > 0.0 else float("inf")
    if stroke < MIN_STROKE_M:
        seen = (
            f"its stroke of {stroke:.3g} m is shorter than the {MIN_STROKE_M:g} m over which "
            "a ball guide's contacts break away"
        )
    else:
        seen = (
            f"its stroke of {stroke:.3g} m is only {steps:.3g} position steps "
            f"({resolution:.3g} m, the encoder's count or the noise)"
        )
    return (
        f"{seen}: friction cannot be told from the noise; record back-and-forth strokes of "
        f"at least {max(MIN_STROKE_M, MIN_STROKE_STEPS * resolution, 1e-3):.3g} m at several "
        "speeds (gms-comp profile writes such a trajectory); if the column is not in "
        f"metres, check its scale (--map position_m={expr}*FACTOR)"
    )


def _looks_like(
    units: tuple[tuple[str, float], ...], fits: Callable[[float], bool], column: str,
    expr: str, named: str,
) -> str:  # fmt: skip
    """The units (at most two) in which every figure is in range, with their ``--map``."""
    found = [
        f"{name} (--map {column}={scaled(expr, factor)})" for name, factor in units if fits(factor)
    ][:2]
    if not found:
        return f"check the column's unit and scale it to {named} (--map {column}=EXPR*FACTOR)"
    return f"it looks like {' or '.join(found)} although the name says {named}"
