"""The physics sections of a config: [bearing], [stand] and [model] (seed Table 1 by default).

They are owned by the physics layer that uses them; :mod:`gms_comp.config` reads and
checks them like every other section.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from gms_comp.config import default_config_path, in_range, parse_section, read_toml
from gms_comp.errors import ConfigError
from gms_comp.physics.contact import contact_problem, hertz_contact
from gms_comp.validation import MAX_BALL_LOADS

#: Smallest groove radius over ball radius: the contact ellipse's aspect ratio grows
#: without bound as the groove closes on the ball (Ry / Rx = Rr / (Rr - R) <= 201).
MIN_GROOVE_RATIO = 1.005


@dataclass(frozen=True)
class BearingConfig:
    """Ball, raceway and material of one ball/raceway contact (seed Table 1)."""

    ball_radius_m: float = field(metadata=in_range(1e-4, 0.05))
    raceway_radius_m: float = field(metadata=in_range(1e-4, 1.0))
    youngs_modulus_ball_Pa: float = field(metadata=in_range(1e8, 1.5e12))
    youngs_modulus_raceway_Pa: float = field(metadata=in_range(1e8, 1.5e12))
    poisson_ratio_ball: float = field(metadata=in_range(0.0, 0.5, hi_open=True))
    poisson_ratio_raceway: float = field(metadata=in_range(0.0, 0.5, hi_open=True))
    friction_coefficient: float = field(metadata=in_range(1e-6, 1.0))
    slip_exaggeration: float = field(default=1.0, metadata=in_range(1.0, 10.0))

    def problems(self) -> list[tuple[str, str]]:
        """`raceway_radius_m` >= 1.005 x `ball_radius_m`: the groove is wider than the ball.

        Returns ``(key, reason)`` pairs for values that are wrong together.
        """
        if self.raceway_radius_m < MIN_GROOVE_RATIO * self.ball_radius_m:
            return [
                (
                    "raceway_radius_m",
                    f"must be >= {MIN_GROOVE_RATIO:g} x ball_radius_m "
                    f"({self.raceway_radius_m:g} vs {self.ball_radius_m:g}): a groove must be "
                    "wider than the ball (closer conformity has no Hertz solution)",
                )
            ]
        return []


@dataclass(frozen=True)
class StandConfig:
    """How the balls are loaded and driven (the seed's test stand by default).

    ``rolling_distance_per_travel`` is the distance the contact rolls over the
    raceway per unit carriage travel. On the seed's stand the balls run free
    between the raceway on the moving table and the counter-face held by the
    z-axis, so their centres travel half the table travel and the contact rolls
    0.5 per unit travel (docs/model.md, "Kinematics").
    """

    ball_loads_N: tuple[float, ...] = field(metadata=in_range(1e-3, 1e5, max_items=MAX_BALL_LOADS))
    carriage_velocity_m_s: float = field(default=0.01, metadata=in_range(1e-6, 10.0))
    rolling_distance_per_travel: float = field(default=0.5, metadata=in_range(1e-3, 1.0))


@dataclass(frozen=True)
class ModelConfig:
    """Modelling and numerical choices of the ball model (see docs/model.md).

    ``tangential_stiffness`` selects the reading of the seed's bristle stiffness
    k_q: ``"seed"`` uses E' = 2 E* numerically per mm (the paper's numbers),
    ``"mindlin"`` spreads Mindlin's tangential contact stiffness over the
    contact area. The grid fields set the resolution of the transient model;
    benchmarks/bench_physics.py shows where its results converge.
    """

    tangential_stiffness: Literal["seed", "mindlin"] = "seed"
    steady_nodes_per_area: int = field(default=48, metadata=in_range(2, 1024))
    stripes_per_area: int = field(default=8, metadata=in_range(1, 256))
    bristles_per_stripe: int = field(default=32, metadata=in_range(2, 4096))
    lambda_min: float = field(default=1.0, metadata=in_range(1.0, 1e6))
    lambda_max: float = field(default=100.0, metadata=in_range(1.0, 1e6))
    lambda_count: int = field(default=25, metadata=in_range(2, 1000))
    stop_velocity_m_s: float = field(default=1e-6, metadata=in_range(1e-12, 1e-2))

    def problems(self) -> list[tuple[str, str]]:
        """`lambda_max` > `lambda_min`.

        Returns ``(key, reason)`` pairs for values that are wrong together.
        """
        if self.lambda_max <= self.lambda_min:
            return [
                (
                    "lambda_max",
                    f"must be > lambda_min ({self.lambda_max:g} <= {self.lambda_min:g})",
                )
            ]
        return []


@dataclass(frozen=True)
class BallConfig:
    """The physics part of a config file."""

    path: str
    bearing: BearingConfig
    stand: StandConfig
    model: ModelConfig = ModelConfig()


def load_ball_config(path: str | Path | None = None) -> BallConfig:
    """Load the physics sections of ``path`` (default: the seed's Table 1), each ball
    load checked against the Hertz model's validity (:func:`check_loads`)."""
    p = Path(path) if path is not None else default_config_path()
    doc = read_toml(p)
    cfg = BallConfig(
        path=str(p),
        bearing=parse_section(doc, p, "bearing", BearingConfig),
        stand=parse_section(doc, p, "stand", StandConfig),
        model=parse_section(doc, p, "model", ModelConfig),
    )
    check_loads(cfg, cfg.stand.ball_loads_N, "stand.ball_loads_N")
    return cfg


def check_loads(cfg: BallConfig, loads_N: tuple[float, ...], key: str) -> None:
    """Refuse a ball load whose contact lies outside the Hertz model (a contact ellipse
    as wide as the ball), naming the config file and ``key[i]``. Every reader of ball
    loads (the ball model, the table's load family, ``gms-comp config``) calls it, so
    they refuse the same configs."""
    for i, load in enumerate(loads_N):
        if load in loads_N[:i]:
            continue  # each distinct load once
        problem = contact_problem(hertz_contact(cfg.bearing, load), cfg.bearing.ball_radius_m)
        if problem is not None:
            raise ConfigError(cfg.path, f"{key}[{i}]", problem)
