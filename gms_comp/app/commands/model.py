"""``gms-comp model``: contact, rolling lines and sliding friction of a config's ball set."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from gms_comp.arguments import input_file, output_dir
from gms_comp.physics.ball_model import SteadyResult, steady_state
from gms_comp.physics.config import BallConfig, load_ball_config


def register(subparsers: Any) -> None:
    """Add the ``model`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        "model",
        help="evaluate the ball/raceway friction model of a config",
        description=(
            "Hertz contact, lines of pure rolling and steady sliding friction of the "
            "configured ball set (default: the packaged seed Table 1)."
        ),
    )
    parser.add_argument(
        "config", nargs="?", type=input_file, help="config TOML (default: the seed's Table 1)"
    )
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object (SI units) on stdout only"
    )
    parser.add_argument(
        "--plot",
        type=output_dir,
        metavar="DIR",
        help="write PNGs of the seed's Figs. 3, 4, 5 and 8 into DIR (created)",
    )
    parser.set_defaults(func=run)


def summary(cfg: BallConfig) -> dict[str, Any]:
    """The model's key results as a JSON-ready dict; the first ball stands for the contact."""
    results = [steady_state(cfg, load) for load in cfg.stand.ball_loads_N]
    first: SteadyResult = results[0]
    c = first.contact
    return {
        "config": cfg.path,
        "contact": {
            "normal_load_N": c.normal_load_N,
            "a_m": c.a_m,
            "b_m": c.b_m,
            "p0_Pa": c.p0_Pa,
            "approach_m": c.approach_m,
            "e_star_Pa": c.e_star_Pa,
        },
        "rolling_lines": {
            "beta": first.beta,
            "lambda": first.lam,
            "xi0": first.xi0,
            "b0_m": first.b0_m,
            "b_minus_m": first.b_minus_m,
            "b_plus_m": first.b_plus_m,
            "beta_range_over_lambda": [min(first.betas), max(first.betas)],
        },
        "friction": {
            "tangential_stiffness": cfg.model.tangential_stiffness,
            "k_q_N_per_m3": first.k_q_N_per_m3,
            "sliding_force_per_ball_N": [r.sliding_force_N for r in results],
            "sliding_force_N": sum(r.sliding_force_N for r in results),
        },
    }


def _print_text(data: dict[str, Any]) -> None:
    c, r, f = data["contact"], data["rolling_lines"], data["friction"]
    print(f"config            {data['config']}")
    print(
        f"contact           a = {c['a_m'] * 1e6:.3f} um, b = {c['b_m'] * 1e6:.3f} um, "
        f"p0 = {c['p0_Pa'] / 1e6:.1f} N/mm^2, approach = {c['approach_m'] * 1e6:.4f} um"
    )
    print(
        f"rolling lines     beta = {r['beta']:.4f}, lambda = {r['lambda']:.3f}, "
        f"xi0 = {r['xi0']:.4e}"
    )
    print(
        f"sliding friction  {f['sliding_force_N']:.4f} N for "
        f"{len(f['sliding_force_per_ball_N'])} balls (k_q: {f['tangential_stiffness']})"
    )


def run(args: argparse.Namespace) -> int:
    """Evaluate the ball model of the config; summary, JSON or plots."""
    cfg = load_ball_config(args.config)
    data = summary(cfg)
    if args.json:
        print(json.dumps(data, indent=2))
    else:
        _print_text(data)
    if args.plot is not None:
        from gms_comp.app.plots_physics import write_figures  # matplotlib only when asked for

        for path in write_figures(cfg, args.plot):
            print(f"wrote {path}", file=sys.stderr if args.json else sys.stdout, flush=True)
    return 0
