"""The EMPS benchmark's IDIM-LS reference model and its relative error.

Janot, Gautier, Brunot, *Data Set and Reference Models of EMPS*, 2019 (§3.1-3.4,
§4.2): tau = M ddq + Fv dq + Fc sign(dq) + offset, with position filtered at 100 Hz
(zero phase, 4th-order Butterworth), central differences, the first 49 samples dropped,
every regressor column and tau decimated by 10 (MATLAB ``decimate``), ordinary least
squares. The relative error is 100 ||e|| / ||tau|| on the decimated data. Any model
(ours included) is scored by :func:`relative_error_pct` the same way: since decimation
is linear, decimating the prediction equals predicting from decimated regressors.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.motion import Kinematics, decimate_matlab, kinematics
from gms_comp.measured.traces import Trace

FILTER_CUTOFF_HZ = 100.0  # 5 x the 20 Hz position-loop bandwidth
DROPPED_SAMPLES = 49  # MATLAB n_border = 50, 1-based
DECIMATION = 10  # round(0.8 * 500 / 40)

# Catalogue effects the reference model holds: M (inertia), Fv (viscous), offset; its
# Fc sign(dq) is the baseline's friction level.
REFERENCE_EFFECTS = frozenset({"inertia", "viscous", "offset"})

SYMMETRIC_NAMES = ("M_kg", "Fv_Ns_per_m", "Fc_N", "offset_N")
ASYMMETRIC_NAMES = ("M_kg", "Fv_pos_Ns_per_m", "Fc_pos_N", "Fv_neg_Ns_per_m", "Fc_neg_N")


@dataclass(frozen=True)
class IdimResult:
    """Parameters and benchmark error figures of one IDIM-LS fit."""

    names: tuple[str, ...]
    theta: FloatArray
    std: FloatArray
    relative_error_pct: float
    error_norm: float
    condition_number: float

    def parameters(self) -> dict[str, float]:
        """The identified parameters by name."""
        return {n: float(v) for n, v in zip(self.names, self.theta, strict=True)}


def benchmark_kinematics(trace: Trace) -> tuple[Kinematics, FloatArray]:
    """Filtered kinematics and force with the benchmark's first samples dropped."""
    kin = kinematics(trace, FILTER_CUTOFF_HZ, reflected=False).slice(DROPPED_SAMPLES)
    return kin, trace.force_N[DROPPED_SAMPLES:]


def regressors(kin: Kinematics, asymmetric: bool = False) -> FloatArray:
    """The benchmark's observation matrix at full rate."""
    v = kin.velocity_m_s
    sg = np.sign(v)
    if asymmetric:  # Script_IDIM_LS_Asym_Fric.m: no offset column
        up, down = (1 + sg) / 2, (1 - sg) / 2
        return np.column_stack([kin.acceleration_m_s2, v * up, sg * up, v * down, sg * down])
    return np.column_stack([kin.acceleration_m_s2, v, sg, np.ones_like(v)])


def decimate_columns(x: FloatArray) -> FloatArray:
    """Every column (or a vector) decimated as the benchmark does."""
    if x.ndim == 1:
        return decimate_matlab(x, DECIMATION)
    return np.column_stack([decimate_matlab(c, DECIMATION) for c in x.T])


def relative_error_pct(force_N: FloatArray, predicted_N: FloatArray) -> float:
    """100 ||tau - tau_hat|| / ||tau|| on decimated data, as the benchmark paper scores."""
    y = decimate_columns(force_N)
    e = y - decimate_columns(predicted_N)
    return float(100.0 * np.linalg.norm(e) / np.linalg.norm(y))


def idim_ls(trace: Trace, asymmetric: bool = False) -> IdimResult:
    """Fit the benchmark's reference model by IDIM-LS on ``trace``."""
    kin, tau = benchmark_kinematics(trace)
    xd = decimate_columns(regressors(kin, asymmetric))
    yd = decimate_columns(tau)
    theta = np.asarray(np.linalg.lstsq(xd, yd, rcond=None)[0], dtype=np.float64)
    return _scored(asymmetric, theta, xd, yd)


def cross_test(fit: IdimResult, trace: Trace) -> IdimResult:
    """The same parameters scored on another record (Script_IDIM_LS_CTV.m)."""
    kin, tau = benchmark_kinematics(trace)
    asymmetric = fit.names == ASYMMETRIC_NAMES
    return _scored(
        asymmetric, fit.theta, decimate_columns(regressors(kin, asymmetric)), decimate_columns(tau)
    )


def _scored(asymmetric: bool, theta: FloatArray, xd: FloatArray, yd: FloatArray) -> IdimResult:
    e = yd - xd @ theta
    std = np.std(e, ddof=1) * np.sqrt(np.diag(np.linalg.inv(xd.T @ xd)))
    return IdimResult(
        names=ASYMMETRIC_NAMES if asymmetric else SYMMETRIC_NAMES,
        theta=theta,
        std=std,
        relative_error_pct=float(100.0 * np.linalg.norm(e) / np.linalg.norm(yd)),
        error_norm=float(np.linalg.norm(e)),
        condition_number=float(np.linalg.cond(xd)),
    )


def reference_model_misses(
    effects: Sequence[Mapping[str, Any]], baseline_rms_N: float
) -> list[dict[str, Any]]:
    """The effects the diagnosis kept beyond the reference's M, Fv, Fc and offset.

    ``effects`` is the diagnosis JSON's ranked list; each miss gets its gain, the drop in
    held-out RMS it brought when it was added, relative to the baseline's RMS.
    """
    misses = []
    previous = baseline_rms_N
    for entry in effects:
        if entry["effect"] not in REFERENCE_EFFECTS:
            misses.append(
                {
                    "effect": entry["effect"],
                    "parameters": entry["parameters"],
                    "gain": (previous - entry["heldout_rms_N"]) / baseline_rms_N,
                }
            )
        previous = entry["heldout_rms_N"]
    return misses
