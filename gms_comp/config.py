"""Validated loading of TOML configs into frozen dataclasses.

Every section of a config file maps to a frozen dataclass whose field names
carry their units (``ball_radius_m``, ``normal_load_N``). Values are SI.
A field without a default is required. A field may carry a check in its
metadata (``field(metadata=positive())``); a dataclass may add cross-field
checks through a ``problems()`` method returning ``(key, reason)`` pairs.

Sections are owned by the layer that uses them; :data:`KNOWN_SECTIONS` lists
every section name a gms-comp config may hold, so that a misspelt section is
refused wherever the file is read.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Literal, TypeVar

from gms_comp.errors import ConfigError
from gms_comp.validation import MAX_BALL_LOADS, read_toml_document

KNOWN_SECTIONS = frozenset(
    {
        "bearing",  # ball, raceway, material, friction (physics)
        "stand",  # loads and kinematics of the ball set (physics)
        "model",  # numerical and modelling choices of the ball model (physics)
        "table",  # GMS reduction settings (reduction)
        "plant",  # simulated linear-motor axis (sim)
        "controller",  # cascade controller (sim)
        "scenario",  # trajectory and delays (sim)
        "compensator",  # observer and feedforward (runtime)
        "can",  # CAN transport (firmware_bridge)
        "diagnosis",  # measured-data analysis
        "scaleout",  # Dask scheduler address and TLS files (application)
    }
)

Check = Callable[[Any], "str | None"]

#: Smallest groove radius over ball radius: the contact ellipse's aspect ratio grows
#: without bound as the groove closes on the ball (Ry / Rx = Rr / (Rr - R) <= 201).
MIN_GROOVE_RATIO = 1.005
T = TypeVar("T")


def positive(*, max_items: int | None = None) -> dict[str, Any]:
    """Field metadata: the value must be finite and > 0 (at most ``max_items`` entries)."""
    return {
        "check": lambda v: None if _all(v, lambda x: x > 0) else "must be > 0",
        "range": (0.0, math.inf, "(", ")"),
        "max_items": max_items,
    }


def non_negative() -> dict[str, Any]:
    """Field metadata: the value must be finite and >= 0."""
    return {
        "check": lambda v: None if _all(v, lambda x: x >= 0) else "must be >= 0",
        "range": (0.0, math.inf, "[", ")"),
    }


def in_range(
    lo: float,
    hi: float,
    *,
    hi_open: bool = False,
    lo_open: bool = False,
    max_items: int | None = None,
) -> dict[str, Any]:
    """Field metadata: lo <= value <= hi (``lo_open``/``hi_open`` make a bound strict).

    ``max_items`` caps the number of entries of an array field; it is checked before
    the entries are.
    """
    lower = "(" if lo_open else "["
    upper = ")" if hi_open else "]"

    def inside(x: float) -> bool:
        above = lo < x if lo_open else lo <= x
        below = x < hi if hi_open else x <= hi
        return above and below

    def check(v: Any) -> str | None:
        return None if _all(v, inside) else f"must be in {lower}{lo:g}, {hi:g}{upper}"

    return {"check": check, "range": (lo, hi, lower, upper), "max_items": max_items}


def _all(value: Any, pred: Callable[[float], bool]) -> bool:
    items = value if isinstance(value, tuple) else (value,)
    return all(math.isfinite(x) and pred(x) for x in items)


def default_config_path() -> Path:
    """The packaged default config: the seed's Table 1 and its test stand."""
    return Path(str(resources.files("gms_comp.configs").joinpath("table1.toml")))


def read_toml(path: str | Path) -> dict[str, Any]:
    """Read a config file and refuse unreadable TOML or unknown sections."""
    p = Path(path)
    doc = read_toml_document(p, error=ConfigError)
    for name, value in doc.items():
        if name not in KNOWN_SECTIONS:
            raise ConfigError(
                str(p), name, f"unknown section (known: {', '.join(sorted(KNOWN_SECTIONS))})"
            )
        if not isinstance(value, dict):
            raise ConfigError(str(p), name, "must be a [section] table")
    return doc


def config_hash(path: str | Path) -> str:
    """SHA-256 of a config file's bytes, to tie derived artefacts to their source."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def parse_section(doc: Mapping[str, Any], path: str | Path, section: str, cls: type[T]) -> T:
    """Build dataclass ``cls`` from ``doc[section]``, validating keys, types and values.

    A missing section is allowed when every field of ``cls`` has a default.
    """
    table = doc.get(section, {})
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    where = str(path)
    for key in table:
        if key not in fields:
            raise ConfigError(
                where, f"{section}.{key}", f"unknown key (known: {', '.join(fields)})"
            )
    values: dict[str, Any] = {}
    for name, f in fields.items():
        key = f"{section}.{name}"
        if name not in table:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ConfigError(where, key, "missing required key")
            continue
        cap = f.metadata.get("max_items")
        if cap is not None and isinstance(table[name], list) and len(table[name]) > cap:
            raise ConfigError(
                where, key, f"{len(table[name])} entries, more than the {cap} allowed"
            )
        value = _coerce(table[name], hints[name], where, key)
        check = f.metadata.get("check")
        if check is not None:
            reason = check(value)
            if reason:
                raise ConfigError(where, key, f"{reason}, got {table[name]!r}")
        values[name] = value
    obj = cls(**values)
    problems = getattr(obj, "problems", None)
    if problems is not None:
        for name, reason in problems():
            raise ConfigError(where, f"{section}.{name}", reason)
    return obj


def _coerce(value: Any, hint: Any, where: str, key: str) -> Any:
    """Check ``value`` against a type hint; ints are accepted where floats are expected."""
    origin = typing.get_origin(hint)
    if origin is Literal:
        choices = typing.get_args(hint)
        if value not in choices:
            raise ConfigError(
                where, key, f"must be one of {', '.join(map(repr, choices))}, got {value!r}"
            )
        return value
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(hint)
        last: ConfigError | None = None
        for arg in args:
            try:
                return _coerce(value, arg, where, key)
            except ConfigError as err:
                last = err
        assert last is not None
        raise last
    if origin is tuple:
        (item, _ellipsis) = typing.get_args(hint)
        if not isinstance(value, list) or not value:
            raise ConfigError(where, key, f"must be a non-empty array, got {value!r}")
        return tuple(_coerce(v, item, f"{where}", f"{key}[{i}]") for i, v in enumerate(value))
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(where, key, f"must be a number, got {type(value).__name__} {value!r}")
        if not math.isfinite(value):
            raise ConfigError(where, key, f"must be finite, got {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(
                where, key, f"must be an integer, got {type(value).__name__} {value!r}"
            )
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(where, key, f"must be true or false, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(where, key, f"must be a string, got {type(value).__name__} {value!r}")
        return value
    raise TypeError(f"unsupported config field type {hint!r} for {key}")  # a programming error


# --- physics sections -----------------------------------------------------------------


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
        """``(key, reason)`` pairs for values that are wrong together."""
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
        """``(key, reason)`` pairs for values that are wrong together."""
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
    """Load the physics sections of ``path`` (default: the seed's Table 1)."""
    p = Path(path) if path is not None else default_config_path()
    doc = read_toml(p)
    return BallConfig(
        path=str(p),
        bearing=parse_section(doc, p, "bearing", BearingConfig),
        stand=parse_section(doc, p, "stand", StandConfig),
        model=parse_section(doc, p, "model", ModelConfig),
    )
