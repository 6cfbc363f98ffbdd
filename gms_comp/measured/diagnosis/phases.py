"""Residual of a model by motion phase: where along the motion the model is wrong."""

from __future__ import annotations

import re

import numpy as np

from gms_comp.arrays import BoolArray, FloatArray
from gms_comp.measured.diagnosis.design import rms
from gms_comp.runtime import effects as fx

# |a| above this fraction of the trace's peak acceleration counts as an acceleration phase.
ACCELERATION_FRACTION = 0.2


def phase_masks(ctx: fx.Context, presliding_m: float) -> dict[str, BoolArray]:
    """Boolean masks of the motion phases (a sample belongs to the first that applies):
    presliding after a reversal, break-away after a standstill, standstill, acceleration,
    and steady sliding split by direction and by speed (three bins of equal count)."""
    moving = ctx.moving > 0
    after_reversal = moving & (ctx.distance_since_reversal_m < presliding_m)
    # a break-away starts with the first steps from the rest position, below any speed
    breakaway = (
        (ctx.resting == 0)
        & ~after_reversal
        & ctx.after_rest()
        & (ctx.distance_since_start_m < presliding_m)
    )
    accel = np.abs(ctx.acceleration_m_s2)
    accelerating = (
        moving & ~after_reversal & ~breakaway & (accel > ACCELERATION_FRACTION * np.max(accel))
    )
    masks: dict[str, BoolArray] = {
        "presliding_after_reversal": after_reversal,
        "breakaway_after_standstill": breakaway,
        "standstill": ~moving & ~breakaway,
        "acceleration": accelerating,
    }
    sliding = moving & ~after_reversal & ~breakaway & ~accelerating
    speed = np.abs(ctx.velocity_m_s)
    for name, sign in (("pos", 1.0), ("neg", -1.0)):
        part = sliding & (np.sign(ctx.velocity_m_s) == sign)
        if not np.any(part):
            continue
        edges = np.quantile(speed[part], [0, 1 / 3, 2 / 3, 1])
        for j in range(3):
            upper = speed <= edges[j + 1] if j == 2 else speed < edges[j + 1]
            mask = part & (speed >= edges[j]) & upper
            if np.any(mask):
                v_med = float(np.median(speed[mask]))
                masks[f"sliding_{name}_{v_med:.3g}_m_s"] = mask
    return masks


def residual_by_phase(
    residual_N: FloatArray, masks: dict[str, BoolArray]
) -> dict[str, dict[str, float]]:
    """RMS and mean of the residual, and the share of samples, per phase."""
    n = residual_N.size
    out: dict[str, dict[str, float]] = {}
    for name, mask in masks.items():
        if np.any(mask):
            r = residual_N[mask]
            out[name] = {
                "rms_N": rms(r),
                "mean_N": float(np.mean(r)),
                "fraction": float(np.count_nonzero(mask) / n),
            }
    return out


def phase_label(key: str) -> str:
    """A phase key as words (``sliding_pos_0.0123_m_s`` -> sliding forward, 12.3 mm/s)."""
    m = re.fullmatch(r"sliding_(pos|neg)_(.+)_m_s", key)
    if m:
        way = "forward" if m.group(1) == "pos" else "backward"
        return f"sliding {way}, {1e3 * float(m.group(2)):.3g} mm/s"
    return key.replace("_", " ")
