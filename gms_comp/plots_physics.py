"""PNG analogues of the seed's Figs. 3, 4, 5 and 8 for a config's first ball."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray

from .ball_model import (
    StripeModel,
    friction_torque_Nm,
    lambda_grid,
    steady_state,
    stripe_model,
)
from .config import BallConfig
from .profiles import seed_fig7_profile
from .transient import BallSetFriction

UM = 1e6  # m -> um for axis labels


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
    fig, ax = plt.subplots(figsize=(5, 6))
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
    ax.plot(boundary * UM, ys * UM, color="0.4", lw=1.2, label="stick/slip boundary a0(y)")
    for sign in (1, -1):
        ax.axhline(sign * steady.b0_m * UM, ls="--", color="k", lw=0.8)
    ax.set(
        xlabel="x along motion [um] (entry at -a)",
        ylabel="y [um]",
        title=f"Stick (blue) and slip, beta = {steady.beta:.4f}",
    )
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def fig4_fields(cfg: BallConfig, path: Path) -> None:
    """Bristle displacement and traction over the contact (seed Fig. 4)."""
    load = cfg.stand.ball_loads_N[0]
    steady, model = steady_state(cfg, load), stripe_model(cfg, load)
    x, y, u, traction = _steady_fields(model, steady.xi0)
    fig, axes = plt.subplots(1, 2, figsize=(9, 5.5), sharey=True)
    for ax, field, label in (
        (axes[0], u * 1e9, "displacement u [nm]"),
        (axes[1], traction / 1e6, "traction F [N/mm^2]"),
    ):
        mesh = ax.pcolormesh(x * UM, y * UM, field, shading="auto", cmap="coolwarm")
        fig.colorbar(mesh, ax=ax, label=label)
        ax.set(xlabel="x along motion [um]")
    axes[0].set(ylabel="y [um]")
    fig.suptitle("Steady bristle field (entry at x = -a)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


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
    fig, ax = plt.subplots(figsize=(6, 4.5))
    mesh = ax.pcolormesh(betas, lambdas, np.log10(torque), shading="auto", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="log10 M [N m]")
    ax.plot(steady.betas, steady.lambdas, "w.", ms=4, label="minimum over beta")
    ax.axvline(steady.beta, color="w", ls=":", label=f"beta = {steady.beta:.4f}")
    ax.set(xlabel="beta = b0 / b", ylabel="lambda = rho / b", yscale="log")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def fig8_hysteresis(cfg: BallConfig, path: Path) -> None:
    """Friction of the ball set over the Fig. 7 profile (seed Figs. 7 and 8)."""
    t, x, v = seed_fig7_profile()
    force = BallSetFriction(cfg).force(x, v)
    fig, axes = plt.subplots(2, 1, figsize=(7, 7))
    axes[0].plot(t, x * 1e3)
    axes[0].set(xlabel="time [s]", ylabel="position [mm]", title="Profile (seed Fig. 7)")
    axes[1].plot(x * 1e3, force, lw=1)
    axes[1].set(
        xlabel="position [mm]",
        ylabel="friction force [N]",
        title="Hysteresis of the ball set (seed Fig. 8)",
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


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
