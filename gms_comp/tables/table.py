"""The GMS table file: bristle elements plus where they came from and how good they are.

A table is JSON (read with :func:`json.loads`, never pickle), SI units, keys
carrying their units::

    {"format": "gms-comp-table", "format_version": 4, "gms_comp_version": "0.1.0",
     "units": {...}, "elements": N, "stiffness_N_per_m": [...], "limit_N": [...],
     "velocity_level": {"slip_level": 1.2, "transition_velocity_m_s": 1e-4,
                        "transition_exponent": 2.0, "transition_tail": null,
                        "limit_follows_level": false},
     "attraction_rate_per_s": null,            # null: infinite (Maxwell-slip)
     "viscous_Ns_per_m": 0.0,
     "source": {"config": "...", "sha256": "..."},
     "fidelity": {"rms_rel": ..., "max_rel": ...},
     "load_family": null | {"normal_load_N": [...], "stiffness_N_per_m": [[...]],
                            "limit_N": [[...]]},
     "extensions": [{"effect": "viscous", "parameters": {"name": 1.0}}],
     "extension_context": null | {"standstill_speed_m_s": ..., "reversal_deadband_m": ...,
                                  "rest_band_m": ...},
     "scaled_by": null | {"ball_sets": 40.0, "ball_loads_N": [50.0, ...]}}

A table's forces are the whole axis's friction, whichever command made it; the observer
runs it as it stands (times ``[compensator] friction_level_scale`` only). ``scaled_by``: the
ball sets a physics table's one set was scaled by, and that set's ball loads; null for a
diagnosed table (measured on the whole axis). Versions 1 to 3 held one ball set in a
physics table and are refused.

``extension_context`` is how the extensions were fitted to see the path (when the
axis is at rest, what counts as a reversal; ``gms_comp.runtime.effects.path``): the
observer must see it the same way, but causally: the diagnosis dates a reversal from its
turning point, the observer once the retreat exceeds the deadband. Null or absent: the
runtime's defaults.
``velocity_level.transition_tail`` null or absent: infinite (the exponential approach);
``velocity_level.limit_follows_level`` absent: false (the seed's law; :mod:`gms_comp.gms`).
``limit_N`` are the limits W_i at level s = 1 (at rest). A load family holds
the elements at several ball loads (one row each) for interpolation.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gms_comp import __version__
from gms_comp.arrays import FloatArray
from gms_comp.atomic import write_text
from gms_comp.errors import TableError
from gms_comp.gms import GmsParams
from gms_comp.validation import (
    MAX_FAMILY_LOADS,
    MAX_TABLE_BYTES,
    MAX_TABLE_ELEMENTS,
    JsonReader,
    check_count,
    finite_float,
    is_number,
    parse_json,
    read_text,
    shown,
)

FORMAT = "gms-comp-table"
# 4: whole-axis forces (2 and 3 marked a velocity-level tail and the level's limit law).
FORMAT_VERSION = 4
UNITS = {
    "position": "m",
    "velocity": "m/s",
    "force": "N",
    "stiffness": "N/m",
    "viscous": "N s/m",
    "attraction_rate": "1/s",
    "normal_load": "N",
}
_VERSION = re.compile(r"^(\d+)\.(\d+)\.(\d+)")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

# Upper bounds of a table's numbers: far above any linear guide, low enough that the
# observer's arithmetic (k_i z_i, sums over elements) stays finite.
#: Element stiffness k_i of a table, N/m.
MAX_STIFFNESS_N_PER_M = 1e12
#: Element limit W_i and load-family loads of a table, N.
MAX_FORCE_N = 1e6
#: Viscous coefficient of a table, N s/m.
MAX_VISCOUS_NS_PER_M = 1e7
#: Slip level s of a table.
MAX_SLIP_LEVEL = 10.0
#: Transition velocity of a table's velocity level, m/s.
MAX_TRANSITION_VELOCITY_M_S = 1.0
#: Transition exponent of a table's velocity level.
MAX_TRANSITION_EXPONENT = 10.0
#: Transition tail of a table's velocity level (null: infinite, the exponential approach;
#: a larger tail is written as null: its level is the exponential's within 3e-7).
MAX_TRANSITION_TAIL = 1e6
#: Attraction rate of a table, 1/s (null means infinite: Maxwell-slip).
MAX_ATTRACTION_RATE_PER_S = 1e9
#: Model extensions (catalogue effects) of a table.
MAX_EXTENSIONS = 64
#: The path settings of a table's extensions and their upper bounds (m/s, m, m).
EXTENSION_CONTEXT_KEYS = {
    "standstill_speed_m_s": 1.0,
    "reversal_deadband_m": 1.0,
    "rest_band_m": 1.0,
}

# The schema of a table's numbers, one entry per field (dotted path): whether it must be
# > 0 (else >= 0) and its upper bound. The reader checks each against it; the tests draw
# values from it. ``NULLABLE`` fields may be null (infinite),
# ``OPTIONAL`` ones absent too.
NUMBERS: dict[str, tuple[bool, float]] = {
    "velocity_level.slip_level": (True, MAX_SLIP_LEVEL),
    "velocity_level.transition_velocity_m_s": (True, MAX_TRANSITION_VELOCITY_M_S),
    "velocity_level.transition_exponent": (True, MAX_TRANSITION_EXPONENT),
    "velocity_level.transition_tail": (True, MAX_TRANSITION_TAIL),
    "attraction_rate_per_s": (True, MAX_ATTRACTION_RATE_PER_S),
    "viscous_Ns_per_m": (False, MAX_VISCOUS_NS_PER_M),
    "fidelity.rms_rel": (False, math.inf),
    "fidelity.max_rel": (False, math.inf),
}
NULLABLE = frozenset({"velocity_level.transition_tail", "attraction_rate_per_s"})
#: Fields that may be left out (read as null).
OPTIONAL = frozenset({"velocity_level.transition_tail"})
#: ... and of its per-element lists (one number per element).
VECTORS: dict[str, tuple[bool, float]] = {
    "stiffness_N_per_m": (True, MAX_STIFFNESS_N_PER_M),
    "limit_N": (False, MAX_FORCE_N),
}


@dataclass(frozen=True)
class Fidelity:
    """How closely the GMS follows the ball model, relative to the sliding force."""

    rms_rel: float
    max_rel: float


@dataclass(frozen=True)
class Extension:
    """A model extension (an effect from the measured-data catalogue) and its numbers."""

    effect: str
    parameters: Mapping[str, float]


@dataclass(frozen=True, eq=False)
class LoadFamily:
    """Element sets over a grid of ball loads; rows follow ``normal_load_N`` (increasing)."""

    normal_load_N: FloatArray
    stiffness_N_per_m: FloatArray
    limit_N: FloatArray

    def elements_at(self, normal_load_N: float) -> tuple[FloatArray, FloatArray]:
        """k_i and W_i linearly interpolated in load (clamped to the grid's ends)."""

        def interp(rows: FloatArray) -> FloatArray:
            return np.array([np.interp(normal_load_N, self.normal_load_N, c) for c in rows.T])

        return interp(self.stiffness_N_per_m), interp(self.limit_N)


@dataclass(frozen=True)
class Scaling:
    """What a physics table's single ball set was scaled by to make the whole axis."""

    ball_sets: float
    ball_loads_N: tuple[float, ...]


@dataclass(frozen=True, eq=False)
class GmsTable:
    """A GMS model with its provenance, fidelity and optional extras."""

    params: GmsParams
    source_config: str
    source_sha256: str
    fidelity: Fidelity
    version: str = __version__
    load_family: LoadFamily | None = None
    extensions: tuple[Extension, ...] = field(default_factory=tuple)
    extension_context: Mapping[str, float] | None = None  # keys: EXTENSION_CONTEXT_KEYS
    scaled_by: Scaling | None = None  # None: measured on the whole axis

    @property
    def n_elements(self) -> int:
        """Number of GMS elements in the table."""
        return self.params.n_elements


# --- writing ----------------------------------------------------------------------------


def table_to_dict(table: GmsTable) -> dict[str, Any]:
    """The JSON document of a table."""
    p = table.params
    family = table.load_family
    tail = None if p.transition_tail >= MAX_TRANSITION_TAIL else p.transition_tail
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "gms_comp_version": table.version,
        "units": dict(UNITS),
        "elements": p.n_elements,
        "stiffness_N_per_m": p.stiffness_N_per_m.tolist(),
        "limit_N": p.limit_N.tolist(),
        "velocity_level": {
            "slip_level": p.slip_level,
            "transition_velocity_m_s": p.transition_velocity_m_s,
            "transition_exponent": p.transition_exponent,
            "transition_tail": tail,
            "limit_follows_level": p.limit_follows_level,
        },
        "attraction_rate_per_s": (
            None if math.isinf(p.attraction_rate_per_s) else p.attraction_rate_per_s
        ),
        "viscous_Ns_per_m": p.viscous_Ns_per_m,
        "source": {"config": table.source_config, "sha256": table.source_sha256},
        "fidelity": {"rms_rel": table.fidelity.rms_rel, "max_rel": table.fidelity.max_rel},
        "load_family": None
        if family is None
        else {
            "normal_load_N": family.normal_load_N.tolist(),
            "stiffness_N_per_m": family.stiffness_N_per_m.tolist(),
            "limit_N": family.limit_N.tolist(),
        },
        "extensions": [
            {"effect": e.effect, "parameters": dict(e.parameters)} for e in table.extensions
        ],
        "extension_context": None
        if table.extension_context is None
        else dict(table.extension_context),
        "scaled_by": None
        if table.scaled_by is None
        else {
            "ball_sets": table.scaled_by.ball_sets,
            "ball_loads_N": list(table.scaled_by.ball_loads_N),
        },
    }


def write_table(path: str | Path, table: GmsTable) -> None:
    """Write ``table`` as JSON; the file is replaced atomically."""
    text = json.dumps(table_to_dict(table), indent=1, allow_nan=False)
    write_text(path, text + "\n")


# --- reading ----------------------------------------------------------------------------


def read_table(path: str | Path) -> GmsTable:
    """Read and validate a table file; any defect raises :class:`TableError`."""
    p = Path(path)
    text = read_text(p, max_bytes=MAX_TABLE_BYTES, what="table file", error=TableError)
    doc = parse_json(text, str(p), error=TableError)
    return table_from_dict(doc, str(p))


def table_from_dict(doc: Any, where: str) -> GmsTable:
    """Validate a parsed table document; ``where`` names the file in messages."""
    r = _Reader(where)
    if not isinstance(doc, dict):
        raise r.error("", "must be a JSON object")
    if doc.get("format") != FORMAT:
        raise r.error("format", f"must be {FORMAT!r}, got {shown(doc.get('format'))}")
    fv = r.get(doc, "format_version")
    if fv in (1, 2, 3) and not isinstance(fv, bool):
        raise r.error(
            "format_version",
            f"version {fv} predates whole-axis tables (a physics table held one ball set): "
            "remake it (gms-comp table, or gms-comp diagnose --table)",
        )
    if fv != FORMAT_VERSION or isinstance(fv, bool):
        raise r.error("format_version", f"unknown version {shown(fv)} (this reader knows 4)")
    version = r.version(doc, "gms_comp_version")
    units = r.get(doc, "units")
    if units != UNITS:
        raise r.error("units", f"must be {UNITS}, got {shown(units)}")
    n = r.get(doc, "elements")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise r.error("elements", f"must be a positive integer, got {shown(n)}")
    check_count(where, "elements", n, MAX_TABLE_ELEMENTS, "elements", error=TableError)
    k, w = (r.array(r.get(doc, key), key, n, *VECTORS[key]) for key in VECTORS)
    numbers = {key: r.schema_number(doc, key) for key in NUMBERS}
    law = r.get(doc, "velocity_level").get("limit_follows_level", False)
    if not isinstance(law, bool) or (law and numbers["attraction_rate_per_s"] != math.inf):
        why = "must be true or false" if not isinstance(law, bool) else "needs a null attraction"
        raise r.error("velocity_level.limit_follows_level", f"{why}, got {shown(law)}")
    params = GmsParams(
        k,
        w,
        slip_level=numbers["velocity_level.slip_level"],
        transition_velocity_m_s=numbers["velocity_level.transition_velocity_m_s"],
        transition_exponent=numbers["velocity_level.transition_exponent"],
        attraction_rate_per_s=numbers["attraction_rate_per_s"],
        viscous_Ns_per_m=numbers["viscous_Ns_per_m"],
        transition_tail=numbers["velocity_level.transition_tail"],
        limit_follows_level=law,
    )
    source = r.get(doc, "source")
    return GmsTable(
        params=params,
        source_config=r.string(source, "source.config"),
        source_sha256=r.sha256(source, "source.sha256"),
        fidelity=Fidelity(rms_rel=numbers["fidelity.rms_rel"], max_rel=numbers["fidelity.max_rel"]),
        version=version,
        load_family=r.load_family(doc, n),
        extensions=r.extensions(doc),
        extension_context=r.extension_context(doc),
        scaled_by=r.scaling(doc),
    )


class _Reader(JsonReader):
    """Field accessors that raise :class:`TableError` naming the file and the field."""

    def __init__(self, where: str) -> None:
        super().__init__(where, TableError)
        self.where = where

    def error(self, key: str, reason: str) -> TableError:
        """The refusal of field ``key`` (a :class:`TableError`)."""
        return TableError(self.where, key, reason)

    def schema_number(self, doc: Any, key: str) -> float:
        """Field ``key`` of :data:`NUMBERS` (a null one of :data:`NULLABLE` is infinite)."""
        obj = doc
        for part in key.split(".")[:-1]:
            obj = self.get(obj, part)
        name = key.rsplit(".", 1)[-1]
        nullable = key in NULLABLE and isinstance(obj, dict) and obj.get(name) is None
        if nullable and (name in obj or key in OPTIONAL):
            return math.inf
        positive, hi = NUMBERS[key]
        return self.number(obj, key, positive, hi)

    def array(self, value: Any, key: str, n: int | None, positive: bool, hi: float) -> FloatArray:
        """:meth:`vector` as an array."""
        return np.array(self.vector(value, key, n, positive, hi))

    def sha256(self, obj: Any, key: str) -> str:
        value = self.string(obj, key)
        if not re.fullmatch(r"[0-9a-f]{64}", value):
            raise self.error(key, "must be 64 lowercase hex digits")
        return value

    def version(self, obj: Any, key: str) -> str:
        value = self.string(obj, key)
        found = _VERSION.match(value)
        ours = _VERSION.match(__version__)
        assert ours is not None
        if found is None or found.group(1) != ours.group(1):
            raise self.error(
                key, f"unknown version {shown(value)} (this is gms-comp {__version__})"
            )
        return value

    def load_family(self, doc: Any, n: int) -> LoadFamily | None:
        family = self.get(doc, "load_family")
        if family is None:
            return None
        key = "load_family.normal_load_N"
        loads = self.get(family, key)
        if isinstance(loads, list):
            check_count(self.where, key, len(loads), MAX_FAMILY_LOADS, "loads", error=TableError)
        loads = self.array(loads, key, None, True, MAX_FORCE_N)
        if np.any(np.diff(loads) <= 0):
            raise self.error(key, "must be increasing")
        rows = []
        for name, positive, hi in (
            ("stiffness_N_per_m", True, MAX_STIFFNESS_N_PER_M),
            ("limit_N", False, MAX_FORCE_N),
        ):
            key = f"load_family.{name}"
            value = self.get(family, key)
            if not isinstance(value, list) or len(value) != loads.size:
                raise self.error(key, f"must hold {loads.size} rows")
            rows.append(
                np.array(
                    [self.array(v, f"{key}[{i}]", n, positive, hi) for i, v in enumerate(value)]
                )
            )
        return LoadFamily(loads, rows[0], rows[1])

    def scaling(self, doc: Any) -> Scaling | None:
        found, key = self.get(doc, "scaled_by"), "scaled_by.ball_loads_N"
        if found is None:
            return None
        loads = self.vector(self.get(found, key), key, None, True, MAX_FORCE_N)
        return Scaling(self.number(found, "scaled_by.ball_sets", True, MAX_FORCE_N), tuple(loads))

    def extension_context(self, doc: Any) -> dict[str, float] | None:
        context = doc.get("extension_context")
        if context is None:
            return None
        if not isinstance(context, dict):
            raise self.error("extension_context", "must be a JSON object or null")
        unknown = sorted(set(context) - set(EXTENSION_CONTEXT_KEYS))
        if unknown:
            raise self.error(
                f"extension_context.{unknown[0]}",
                f"unknown key (known: {', '.join(EXTENSION_CONTEXT_KEYS)})",
            )
        return {
            name: self.number(context, f"extension_context.{name}", False, hi)
            for name, hi in EXTENSION_CONTEXT_KEYS.items()
        }

    def extensions(self, doc: Any) -> tuple[Extension, ...]:
        items = doc.get("extensions", [])
        if not isinstance(items, list):
            raise self.error("extensions", "must be a list")
        check_count(
            self.where, "extensions", len(items), MAX_EXTENSIONS, "extensions", error=TableError
        )
        out = []
        for i, item in enumerate(items):
            key = f"extensions.{i}"
            effect = self.string(item, f"{key}.effect")
            if not _NAME.match(effect):
                raise self.error(f"{key}.effect", f"must be a name, got {shown(effect)}")
            params = self.get(item, f"{key}.parameters")
            if not isinstance(params, dict):
                raise self.error(f"{key}.parameters", "must be a JSON object")
            values = {}
            for name, value in params.items():
                pkey = f"{key}.parameters.{name}"
                if not _NAME.match(name):
                    raise self.error(pkey, "parameter names must be names")
                if not is_number(value):
                    raise self.error(pkey, f"must be a number, got {shown(value)}")
                number = finite_float(value)
                if number is None or abs(number) > 1e12:
                    raise self.error(pkey, f"must be finite and within +-1e12, got {shown(value)}")
                values[name] = number
            out.append(Extension(effect, values))
        return tuple(out)
