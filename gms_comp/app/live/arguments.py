"""The command-line arguments every live-bus command shares: the config, the bus, a duration."""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path

from firmware_bridge.settings import CanConfig, load_can_config
from gms_comp.arguments import input_file
from gms_comp.config import default_config_path
from gms_comp.validation import InputError


def add_bus_arguments(p: argparse.ArgumentParser) -> None:
    """``CONFIG`` (optional), ``--interface`` and ``--channel``."""
    p.add_argument("config", nargs="?", type=input_file, help="config file (default: Table 1)")
    p.add_argument("--interface", help="python-can interface (default: [can] interface)")
    p.add_argument("--channel", help="python-can channel (default: [can] channel)")


def bus_config(args: argparse.Namespace) -> tuple[Path, CanConfig]:
    """The config file given (or the packaged one) and its ``[can]`` section, with the
    command line's interface and channel."""
    path = args.config if args.config is not None else default_config_path()
    overrides = {k: v for k in ("interface", "channel") if (v := getattr(args, k)) is not None}
    return path, replace(load_can_config(path), **overrides)


def checked_duration(value: float, limit_s: float, option: str = "--duration") -> float:
    """``value`` if within ``(0, limit_s]`` s, else a one-line refusal."""
    if not (math.isfinite(value) and 0 < value <= limit_s):
        raise InputError(option, "", f"must be in (0, {limit_s:g}] s, got {value:g}")
    return value
