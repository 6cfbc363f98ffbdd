"""The observer as C for a drive: a table and ``[compensator]`` made into C99 source.

:func:`export_c` fills the package's templates (``gms_comp/runtime/c/``) with the table
object of :func:`table_object`: the GMS elements as play operators (anchor width
r_i = W_i / k_i), the velocity level s(|v|) and a Stribeck gain of |v| tabulated on
uniform speed grids, the additive extensions a drive can run, and the limits, rate
limit and adaptation of the observer, all float32. The same object is written as bytes
(``gms_table.bin``, little-endian, CRC-32 last) for a download into a drive whose code
was generated for the same counts. docs/in-drive.md gives the model, the cost and the
build.

What a drive cannot run is refused with the reason (:data:`NOT_IN_DRIVE`); effects of
the measurement chain are left out, as the observer leaves them out.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from string import Template

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.atomic import write_bytes, write_text
from gms_comp.errors import TableError
from gms_comp.gms import GmsParams
from gms_comp.runtime import effects as fx
from gms_comp.runtime.observer import CompensatorConfig, physical_extensions
from gms_comp.tables.table import GmsTable

MAGIC = 0x43534D47  # "GMSC" read little-endian
FORMAT = 1
#: The largest interpolation error of a tabulated speed function (level units).
TABLE_TOLERANCE = 1e-5
#: Points of a speed table: powers of two up to this many.
MAX_POINTS = 4096
FILES = ("gms_observer.h", "gms_observer.c")

#: Extensions a drive-side observer does not run, and why.
NOT_IN_DRIVE: dict[type[fx.Effect], str] = {
    fx.DwellTime: "raises each element's limit with the log of its dwell: per-element dwell "
    "clocks and a log per element and step",
    fx.ReversalTransient: "needs the path's reversal detection (deadband, distance since "
    "the turn) and an exp per step; run it controller-side",
    fx.Drift: "a function of the time since the trace began, which a drive's clock does not "
    "share: the level (gms_set_level, the adaptation) carries a drift",
}


class ExportError(TableError):
    """A table the drive-side observer cannot run (names the table and the reason)."""


@dataclass
class TableObject:
    """The C table object: its fields in order, each a C type, a count and its values."""

    fields: list[tuple[str, str, int, list[float]]] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)

    def add(self, name: str, ctype: str, values: FloatArray | list[float] | float) -> None:
        """Append a field (``ctype`` "uint32_t" or "float")."""
        vals = [float(v) for v in np.atleast_1d(np.asarray(values, dtype=float))]
        count = len(vals) if isinstance(values, (list, np.ndarray)) else 0
        self.fields.append((name, ctype, count, vals))

    def _flat(self) -> tuple[str, list[float]]:
        fmt = "<" + "".join(
            ("I" if t == "uint32_t" else "f") * len(v) for _, t, _, v in self.fields
        )
        return fmt, [v for _, _, _, vals in self.fields for v in vals]

    def payload(self) -> bytes:
        """Every field but the CRC, as the drive holds them."""
        fmt, values = self._flat()
        ints = iter(int(v) for v in values)
        packed = [next(ints) if c == "I" else v for c, v in zip(fmt[1:], values, strict=True)]
        return struct.pack(fmt, *packed)

    def to_bytes(self) -> bytes:
        """The whole object: the payload, then its CRC-32 (zlib's)."""
        body = self.payload()
        return body + struct.pack("<I", zlib.crc32(body))

    def declaration(self) -> str:
        """The C struct's fields."""
        lines = [f"    {t} {n}{f'[{c}]' if c else ''};" for n, t, c, _ in self.fields] + [
            "    uint32_t crc32; /* CRC-32 (as zlib's) of every byte before it */"
        ]
        return "\n".join(lines)

    def initializer(self) -> str:
        """The C initializer of the struct, CRC included."""
        crc = zlib.crc32(self.payload())

        def c(t: str, v: float) -> str:
            if t == "uint32_t":
                return f"{int(v)}u"
            return f"{float(np.float32(v)):.8e}f"  # 9 digits: the float32 exactly

        out = []
        for n, t, count, vals in self.fields:
            text = ", ".join(c(t, v) for v in vals)
            out.append(f"    /* {n} */ {{{text}}}," if count else f"    /* {n} */ {text},")
        out.append(f"    /* crc32 */ {crc}u,")
        return "\n".join(out)


def _grid(function: Callable[[FloatArray], FloatArray], end_m_s: float) -> tuple[int, float]:
    """The fewest points (a power of two) of a uniform grid over [0, end] whose linear
    interpolation of ``function`` stays within :data:`TABLE_TOLERANCE`; and the points
    per m/s."""
    n = 2
    while n <= MAX_POINTS:
        speeds = np.linspace(0.0, end_m_s, n)
        fine = np.linspace(0.0, end_m_s, 16 * (n - 1) + 1)
        error = np.max(np.abs(np.interp(fine, speeds, function(speeds)) - function(fine)))
        if error <= TABLE_TOLERANCE:
            return n, (n - 1) / end_m_s
        n *= 2
    raise ExportError(
        "table", "velocity_level", f"a speed function needs more than {MAX_POINTS} points"
    )


def _settled(function: Callable[[FloatArray], FloatArray], scale_m_s: float) -> float:
    """A speed beyond which ``function`` is its limit within a tenth of the tolerance."""
    far = float(function(np.array([1e3 * scale_m_s]))[0])
    speed = scale_m_s
    while abs(float(function(np.array([speed]))[0]) - far) > 0.1 * TABLE_TOLERANCE:
        speed *= 1.25
    return speed


def _speed_table(function: Callable[[FloatArray], FloatArray], scale_m_s: float) -> tuple[
    FloatArray, float
]:  # fmt: skip
    """``function`` tabulated on a uniform speed grid: values and points per m/s."""
    end = _settled(function, scale_m_s)
    n, per = _grid(function, end)
    return function(np.arange(n) / per), per


@dataclass(frozen=True)
class Extensions:
    """The additive extensions as the C observer holds them."""

    viscous_Ns_per_m: float = 0.0
    speed_Ns_per_m: float = 0.0  # times |v| (a direction asymmetry)
    offset_N: float = 0.0
    stribeck: tuple[tuple[float, float], ...] = ()  # (ratio - 1, v_s) each
    ripples: tuple[tuple[float, float, float], ...] = ()  # (A, 1/lambda, phase / 2 pi)


# How each extension a drive runs enters the C observer's terms.
_DRIVE_FORMS: dict[type[fx.Effect], Callable[[Extensions, fx.Effect], Extensions]] = {
    fx.Viscous: lambda x, e: replace(x, viscous_Ns_per_m=x.viscous_Ns_per_m + e.coefficients()[0]),
    fx.DirectionAsymmetry: lambda x, e: replace(
        x, speed_Ns_per_m=x.speed_Ns_per_m + 0.5 * e.coefficients()[0]
    ),
    fx.Offset: lambda x, e: replace(x, offset_N=x.offset_N + e.coefficients()[0]),
    fx.Stribeck: lambda x, e: replace(
        x, stribeck=(*x.stribeck, (float(e.coefficients()[0]), e.shape()["v_s_m_per_s"]))
    ),
    fx.PositionRipple: lambda x, e: replace(
        x, ripples=(*x.ripples, _ripple(e.coefficients(), e.shape()["wavelength_m"]))
    ),
}


def _ripple(coefficients: FloatArray, wavelength_m: float) -> tuple[float, float, float]:
    """(A, 1 / lambda, phi / 2 pi) of a ripple ``a sin + b cos`` of 2 pi x / lambda."""
    a, b = (float(c) for c in coefficients)
    return math.hypot(a, b), 1.0 / wavelength_m, math.atan2(b, a) / (2 * math.pi)


def drive_extensions(table: GmsTable, where: str) -> Extensions:
    """The table's physical extensions as :class:`Extensions`; refuses those a drive
    does not run."""
    found = Extensions()
    for e in physical_extensions(table):
        form = _DRIVE_FORMS.get(type(e))
        if form is None:
            why = NOT_IN_DRIVE.get(type(e), "it has no drive-side form")
            raise ExportError(where, f"extensions: {e.name}", f"not exported to C: {why}")
        found = form(found, e)
    return found


def table_object(
    table: GmsTable,
    config: CompensatorConfig,
    force_constant_N_per_A: float,
    rate_Hz: float,
    where: str = "table",
) -> TableObject:
    """The C table object of ``table`` for an observer stepping at ``rate_Hz``."""
    p: GmsParams = table.params
    if math.isfinite(p.attraction_rate_per_s):
        raise ExportError(
            where, "attraction_rate_per_s",
            "a finite attraction rate needs each slipping element's force as state and an "
            "exp per step: not exported (tables from gms-comp table and diagnose have none)",
        )  # fmt: skip
    ext = drive_extensions(table, where)
    level, level_per = _speed_table(p.level, p.transition_velocity_m_s)

    def stribeck_gain(v: FloatArray) -> FloatArray:
        return sum((g * np.exp(-((v / vs) ** 2)) for g, vs in ext.stribeck), np.zeros_like(v))

    if ext.stribeck:
        gain, gain_per = _speed_table(stribeck_gain, min(vs for _, vs in ext.stribeck))
    else:
        gain, gain_per = np.zeros(1), 1.0
    ripples = np.array(ext.ripples).reshape(-1, 3) if ext.ripples else np.zeros((0, 3))
    slots = max(1, len(ripples))
    padded = np.zeros((slots, 3))
    padded[: len(ripples)] = ripples
    lo, hi = config.adaptation_level_bounds
    o = TableObject()
    counts = {
        "magic": MAGIC, "format": FORMAT, "n_elements": p.n_elements,
        "level_points": level.size, "stribeck_points": gain.size, "ripples": len(ripples),
        "limit_follows_level": int(p.limit_follows_level),
    }  # fmt: skip
    for key, count in counts.items():
        o.add(key, "uint32_t", float(count))
    o.counts = {k: int(v) for k, v in counts.items()}
    o.add("stiffness_N_per_m", "float", p.stiffness_N_per_m)
    o.add("width_m", "float", p.limit_N / p.stiffness_N_per_m)
    o.add("limit_N", "float", p.limit_N)
    o.add("level_points_per_m_s", "float", level_per)
    o.add("level", "float", level)
    o.add("stribeck_points_per_m_s", "float", gain_per)
    o.add("stribeck", "float", gain)
    for name, value in (
        ("viscous_Ns_per_m", p.viscous_Ns_per_m),
        ("extension_viscous_Ns_per_m", ext.viscous_Ns_per_m),
        ("extension_speed_Ns_per_m", ext.speed_Ns_per_m),
        ("offset_N", ext.offset_N),
    ):
        o.add(name, "float", value)
    o.add("ripple_amplitude_N", "float", padded[:, 0])
    o.add("ripple_cycles_per_m", "float", padded[:, 1])
    o.add("ripple_phase_cycles", "float", padded[:, 2])
    for name, value in (
        ("amps_per_N", 1.0 / force_constant_N_per_A),
        ("current_limit_A", config.current_limit_A),
        ("max_step_A", config.rate_limit_A_per_s / rate_Hz),
        ("initial_level", config.friction_level_scale),
        ("adaptation_gain", min(1.0, config.adaptation_rate_per_s / rate_Hz)),
        ("adaptation_min_velocity_m_s", config.adaptation_min_velocity_m_s),
        ("adaptation_max_inertial_share", config.adaptation_max_inertial_share),
        ("adaptation_lo", lo),
        ("adaptation_hi", hi),
    ):
        o.add(name, "float", value)
    return o


def _template(name: str) -> Template:
    return Template(resources.files("gms_comp.runtime").joinpath(f"c/{name}.in").read_text())


def export_c(
    table: GmsTable,
    out_dir: Path,
    config: CompensatorConfig,
    force_constant_N_per_A: float,
    rate_Hz: float,
    where: str = "table",
) -> tuple[list[Path], TableObject]:
    """Write gms_observer.h, gms_observer.c and gms_table.bin into ``out_dir``."""
    obj = table_object(table, config, force_constant_N_per_A, rate_Hz, where)
    c = obj.counts
    values = {
        "source": table.source_config, "sha256": table.source_sha256, "rate_Hz": f"{rate_Hz:g}",
        "n": c["n_elements"], "level_points": c["level_points"],
        "stribeck_points": c["stribeck_points"], "ripples": c["ripples"],
        "ripple_slots": max(1, c["ripples"]), "limit_follows_level": c["limit_follows_level"],
        "table_bytes": len(obj.to_bytes()), "struct_fields": obj.declaration(),
        "table_initializer": obj.initializer(),
    }  # fmt: skip
    written = []
    for name in FILES:
        written.append(write_text(out_dir / name, _template(name).substitute(values)))
    written.append(write_bytes(out_dir / "gms_table.bin", obj.to_bytes()))
    return written, obj
