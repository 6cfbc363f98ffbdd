"""PNG analogues of the seed's Figs. 3, 4, 5 and 8 for a config's first ball.

Every figure has a title naming the seed figure it stands for and the ball load, and
every axis its quantity and unit. Files are written atomically (:mod:`gms_comp.atomic`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from numpy.typing import NDArray

from gms_comp.atomic import atomic_path
from gms_comp.physics.ball_model import (
    StripeModel,
    friction_torque_Nm,
    lambda_grid,
    steady_state,
    stripe_model,
)
from gms_comp.physics.config import BallConfig
from gms_comp.physics.profiles import seed_fig7_profile
from gms_comp.physics.transient import BallSetFriction

UM = 1e6  # m -> um for axis labels
X_LABEL = "x along the motion [µm] (balls enter at x = -a)"
Y_LABEL = "y across the motion [µm]"


def _save(fig: Figure, path: Path) -> None:
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=120)
    finally:
        plt.close(fig)


def _load_text(cfg: BallConfig) -> str:
    return f"first ball of {len(cfg.stand.ball_loads_N)}, load {cfg.stand.ball_loads_N[0]:g} N"


def _steady_fields(model: StripeModel, xi0: float, n: int = 301) -> tuple[NDArray[np.float64], ...]:
    """Steady u(x, y) and traction F(x, y) on a grid; NaN outside the ellipse."""
    a, b = model.contact.a_m, model.contact.b_m
    x, y = np.meshgrid(np.linspace(-a, a, n), np.linspace(-b, b, n))
    half = model.contact.half_length_m(y)
    inside = np.abs(x) < half
    xi = model.slip_ratio(y, xi0)
    umax = model.slip_limit_m(y)
    u = np.clip(xi * (x + half), -umax, umax)
    saturated = np.abs(u) >= umax * (1 - 1e-12)
    traction = model.k_q_N_per_m3 * u * np.where(saturated, model.slip_exaggeration, 1.0)
    return x, y, np.where(inside, u, np.nan), np.where(inside, traction, np.nan)


def fig3_stick_slip(cfg: BallConfig, path: Path) -> None:
    """Stick and slip areas of the contact ellipse with the rolling lines (seed Fig. 3)."""
    load = cfg.stand.ball_loads_N[0]
    steady, model = steady_state(cfg, load), stripe_model(cfg, load)
    x, y, u, _ = _steady_fields(model, steady.xi0)
    stick = np.abs(u) < model.slip_limit_m(y) * (1 - 1e-12)
    fig, ax = plt.subplots(figsize=(6, 7))
    ax.contourf(
        x * UM,
        y * UM,
        np.where(np.isnan(u), np.nan, stick),
        levels=[-0.5, 0.5, 1.5],
        colors=["#d9d9d9", "#4c72b0"],
    )
    ys = np.linspace(-model.contact.b_m, model.contact.b_m, 400)
    half = model.contact.half_length_m(ys)
    ax.plot(half * UM, ys * UM, "k", -half * UM, ys * UM, "k")
    boundary = -half + model.stick_length_m(ys, steady.xi0)
    ax.plot(boundary * UM, ys * UM, color="0.4", lw=1.2)
    for sign in (1, -1):
        ax.axhline(sign * steady.b0_m * UM, ls="--", color="k", lw=0.8)
    ax.set(
        xlabel=X_LABEL,
        ylabel=Y_LABEL,
        title=(
            "Stick and slip areas of the contact (seed Fig. 3)\n"
            f"{_load_text(cfg)}, beta = {steady.beta:.4f}"
        ),
    )
    handles = [
        Patch(color="#4c72b0", label="stick"),
        Patch(color="#d9d9d9", label="slip"),
        plt.Line2D([], [], color="0.4", lw=1.2, label="stick/slip boundary a0(y)"),
        plt.Line2D(
            [],
            [],
            color="k",
            ls="--",
            lw=0.8,
            label=f"lines of pure rolling, y = ±{steady.b0_m * UM:.1f} µm",
        ),
    ]
    ax.legend(handles=handles, loc="lower right", fontsize=8)
    fig.tight_layout()
    _save(fig, path)


def fig4_fields(cfg: BallConfig, path: Path) -> None:
    """Bristle displacement and traction over the contact (seed Fig. 4)."""
    load = cfg.stand.ball_loads_N[0]
    steady, model = steady_state(cfg, load), stripe_model(cfg, load)
    x, y, u, traction = _steady_fields(model, steady.xi0)
    fig, axes = plt.subplots(1, 2, figsize=(9, 5.5), sharey=True)
    for ax, field, label, title in (
        (axes[0], u * 1e9, "bristle displacement u [nm]", "Bristle displacement u(x, y)"),
        (axes[1], traction / 1e6, "traction F [N/mm²]", "Tangential traction F(x, y)"),
    ):
        mesh = ax.pcolormesh(x * UM, y * UM, field, shading="auto", cmap="coolwarm")
        fig.colorbar(mesh, ax=ax, label=label)
        ax.set(xlabel=X_LABEL, title=title)
    axes[0].set(ylabel=Y_LABEL)
    fig.suptitle(
        f"Steady rolling: fields over the contact ellipse (seed Fig. 4), {_load_text(cfg)}"
    )
    fig.tight_layout()
    _save(fig, path)


def fig5_torque_map(cfg: BallConfig, path: Path) -> None:
    """Friction torque M over beta and lambda (seed Fig. 5)."""
    load = cfg.stand.ball_loads_N[0]
    steady, model = steady_state(cfg, load), stripe_model(cfg, load)
    betas = np.linspace(0.05, 0.95, 91)
    lambdas = lambda_grid(cfg.model)
    n = cfg.model.steady_nodes_per_area
    torque = np.array(
        [[friction_torque_Nm(model, float(bt), float(lm), n) for bt in betas] for lm in lambdas]
    )
    fig, ax = plt.subplots(figsize=(7, 5.5))
    mesh = ax.pcolormesh(betas, lambdas, np.log10(torque), shading="auto", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="friction torque M: log10(M / N m)")
    ax.plot(steady.betas, steady.lambdas, "w.", ms=4, label="minimum over beta at each lambda")
    ax.axvline(steady.beta, color="w", ls=":", label=f"rolling line beta = {steady.beta:.4f}")
    ax.set(
        xlabel="beta = b0 / b: position of the rolling lines [-]",
        ylabel="lambda = rho / b: their radius of curvature [-]",
        yscale="log",
        title=f"Friction torque over the rolling-line position (seed Fig. 5)\n{_load_text(cfg)}",
    )
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    _save(fig, path)


def fig8_hysteresis(cfg: BallConfig, path: Path) -> None:
    """Friction of the ball set over the Fig. 7 profile (seed Figs. 7 and 8)."""
    t, x, v = seed_fig7_profile()
    force = BallSetFriction(cfg).force(x, v)
    fig, axes = plt.subplots(2, 1, figsize=(7, 7))
    axes[0].plot(t, x * 1e3)
    axes[0].set(
        xlabel="time [s]",
        ylabel="carriage position [mm]",
        title="Position profile: 0.1 mm steps out and back (seed Fig. 7)",
    )
    axes[1].plot(x * 1e3, force, lw=1)
    axes[1].set(
        xlabel="carriage position [mm]",
        ylabel="friction force [N]",
        title="Friction force over position: hysteresis (seed Fig. 8)",
    )
    loads = ", ".join(f"{q:g}" for q in cfg.stand.ball_loads_N)
    fig.suptitle(f"Transient friction of the ball set (ball loads {loads} N)")
    fig.tight_layout()
    _save(fig, path)


def write_figures(cfg: BallConfig, directory: Path) -> list[Path]:
    """Write the four figures into ``directory`` (created) and return their paths."""
    directory.mkdir(parents=True, exist_ok=True)
    figures = {
        "fig3_stick_slip.png": fig3_stick_slip,
        "fig4_fields.png": fig4_fields,
        "fig5_torque_map.png": fig5_torque_map,
        "fig8_hysteresis.png": fig8_hysteresis,
    }
    paths = []
    for name, draw in figures.items():
        draw(cfg, directory / name)
        paths.append(directory / name)
    return paths
