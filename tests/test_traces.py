"""Trace loading: canonical CSV, EMPS .mat, explicit mappings and every bad-input rule."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import given, settings
from hypothesis import strategies as st

from gms_comp.errors import GmsCompError, TraceError
from gms_comp.measured import trace_csv
from gms_comp.measured.traces import Trace, load_trace, parse_mapping, write_trace

EMPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "emps"
needs_emps = pytest.mark.skipif(
    not (EMPS / "DATA_EMPS.mat").is_file(), reason=f"EMPS data not found in {EMPS}"
)


def _csv(tmp_path: Path, text: str, name: str = "t.csv") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _good_rows(n: int = 200) -> str:
    t = np.arange(n) * 1e-3
    x = 1e-3 * np.sin(2 * np.pi * t)
    f = np.cos(2 * np.pi * t)
    return "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, x, f, strict=True))


def test_canonical_csv_round_trip(tmp_path: Path) -> None:
    n = 150
    t = np.arange(n) * 2e-3
    trace = Trace(
        source="mem",
        time_s=t,
        position_m=1e-3 * np.sin(t),
        force_N=5.0 * np.cos(20.0 * t),
        velocity_m_s=1e-3 * np.cos(t),
    )
    p = tmp_path / "rt.csv"
    write_trace(p, trace)
    back = load_trace(p)
    for name in ("time_s", "position_m", "force_N", "velocity_m_s"):
        np.testing.assert_allclose(getattr(back, name), getattr(trace, name), rtol=1e-11)
    assert back.current_A is None
    assert back.force_kind is None


def test_error_names_file_and_missing_column(tmp_path: Path) -> None:
    p = _csv(tmp_path, "time_s,position_m,F [N]\n0,0,0\n1,1,1\n")
    with pytest.raises(TraceError, match=r"t\.csv: missing column 'force_N'") as err:
        load_trace(p)
    # the header found, and the --map that names a column of it
    assert "(the file's columns: time_s, position_m, F [N])" in str(err.value)
    assert """--map 'force_N="F [N]"'""" in str(err.value)


def test_non_numeric_cell_names_row_and_column(tmp_path: Path) -> None:
    text = "time_s,position_m,force_N\n" + _good_rows(5) + "\n0.006,abc,1\n"
    with pytest.raises(TraceError, match=r"row 7, column position_m: not a number 'abc'"):
        load_trace(_csv(tmp_path, text))


@pytest.mark.parametrize("cell", ["nan", "inf", "-inf"])
def test_nan_inf_refused(tmp_path: Path, cell: str) -> None:
    text = "time_s,position_m,force_N\n0,0,1\n0.001,0.001," + cell + "\n"
    with pytest.raises(TraceError, match=r"row 3, column force_N: .* not finite"):
        load_trace(_csv(tmp_path, text))


def test_time_not_increasing(tmp_path: Path) -> None:
    lines = _good_rows(200).split("\n")
    lines[50] = lines[49]  # a repeated row: its time stamp at file row 52
    text = "time_s,position_m,force_N\n" + "\n".join(lines) + "\n"
    with pytest.raises(TraceError, match=r"row 52, column time_s: time stamp .* repeats"):
        load_trace(_csv(tmp_path, text))
    lines[50] = "0.0001,0,0"  # back in time at file row 52
    text = "time_s,position_m,force_N\n" + "\n".join(lines) + "\n"
    with pytest.raises(TraceError, match=r"row 52, column time_s: time does not increase"):
        load_trace(_csv(tmp_path, text))


def test_too_few_samples(tmp_path: Path) -> None:
    text = "time_s,position_m,force_N\n" + _good_rows(20) + "\n"
    with pytest.raises(TraceError, match=r"20 samples, the analysis needs at least 100"):
        load_trace(_csv(tmp_path, text))


def test_no_motion(tmp_path: Path) -> None:
    rows = "\n".join(f"{i * 1e-3},0.5,{i}" for i in range(200))
    with pytest.raises(TraceError, match=r"column position_m: no motion"):
        load_trace(_csv(tmp_path, "time_s,position_m,force_N\n" + rows + "\n"))


def test_ragged_row(tmp_path: Path) -> None:
    text = "time_s,position_m,force_N\n0,0,0\n0.001,0\n"
    with pytest.raises(TraceError, match=r"row 3: 2 cells, the header has 3"):
        load_trace(_csv(tmp_path, text))


def test_unknown_format_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(TraceError, match="file not found"):
        load_trace(tmp_path / "nope.csv")
    with pytest.raises(TraceError, match="unknown trace format"):
        load_trace(_csv(tmp_path, "x", name="t.txt"))


def test_trace_error_is_project_and_builtin_error() -> None:
    assert issubclass(TraceError, GmsCompError)
    assert issubclass(TraceError, ValueError)


def test_millimetre_positions_are_refused_with_the_mapping_to_use(tmp_path: Path) -> None:
    n = 200
    t = np.arange(n) * 1e-3
    rows = "\n".join(f"{a},{300 * np.sin(10 * a)},{1.0}" for a in t)  # a 300 "m" stroke
    p = _csv(tmp_path, "time_s,position_m,force_N\n" + rows + "\n")
    with pytest.raises(TraceError, match=r"column position_m: its stroke .* looks like mm") as err:
        load_trace(p)
    assert "--map position_m=position_m*0.001" in str(err.value)
    # The suggested mapping is accepted and scales to a plausible stroke.
    trace = load_trace(p, parse_mapping(["position_m=position_m*0.001"], "cli") | _ids())
    assert np.ptp(trace.position_m) == pytest.approx(np.ptp(300e-3 * np.sin(10 * t)))


def _ids() -> dict[str, str]:
    return {"time_s": "time_s", "force_N": "force_N"}


def test_micrometre_positions_through_a_mapping_name_the_source(tmp_path: Path) -> None:
    n = 200
    t = np.arange(n) * 1e-3
    rows = "\n".join(f"{a},{2e5 * np.sin(10 * a)},{1.0}" for a in t)  # 0.2 m in um
    p = _csv(tmp_path, "time_s,pos_um,force_N\n" + rows + "\n")
    mapping = {"time_s": "time_s", "position_m": "pos_um", "force_N": "force_N"}
    with pytest.raises(TraceError, match=r"looks like um \(--map position_m=pos_um\*1e-06\)"):
        load_trace(p, mapping)


def test_velocity_in_mm_per_s_and_constant_velocity_are_refused(tmp_path: Path) -> None:
    n = 200
    t = np.arange(n) * 1e-3
    x = 5e-3 * np.sin(2 * np.pi * 2 * t)
    for v, message in (
        (1e3 * 5e-3 * 4 * np.pi * np.cos(4 * np.pi * t), r"looks like mm/s .*velocity_m_s\*0.001"),
        (np.full(n, 0.25), r"velocity_m_s: is constant \(0.25 m/s\) while the position moves"),
    ):
        rows = "\n".join(f"{a},{b},1.0,{c}" for a, b, c in zip(t, x, v, strict=True))
        p = _csv(tmp_path, "time_s,position_m,force_N,velocity_m_s\n" + rows + "\n")
        with pytest.raises(TraceError, match=message):
            load_trace(p)


def test_emps_named_matrix_is_refused(tmp_path: Path) -> None:
    n = 300
    t = np.arange(n) * 1e-3
    p = tmp_path / "e2.mat"
    both = np.column_stack([0.1 * t, 0.2 * t])
    scipy.io.savemat(p, {"t": t[:, None], "qm": both, "vir": t[:, None], "gtau": np.array([[1.0]])})
    with pytest.raises(TraceError, match=r"variable qm: is a 300x2 matrix, .* must be a vector"):
        load_trace(p)


def test_mat_variable_is_refused_by_declared_size_before_loading(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import gms_comp.measured.traces as traces

    n = 300
    t = np.arange(n) * 1e-3
    p = tmp_path / "e.mat"
    scipy.io.savemat(
        p,
        {"t": t[:, None], "qm": t[:, None], "vir": t[:, None], "gtau": np.array([[1.0]])},
        do_compression=True,
    )

    def no_loading(*args: object, **kwargs: object) -> None:
        raise AssertionError("loadmat must not run on a variable over the cap")

    monkeypatch.setattr(traces, "MAX_TRACE_SAMPLES", 299)
    monkeypatch.setattr(scipy.io, "loadmat", no_loading)
    with pytest.raises(TraceError, match=r"declares 300x1 = 300 elements, more than the 299"):
        load_trace(p)


def test_csv_rows_are_capped_while_reading(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(trace_csv, "MAX_TRACE_SAMPLES", 150)
    p = _csv(tmp_path, "time_s,position_m,force_N\n" + _good_rows(200) + "\n")
    with pytest.raises(TraceError, match=r"row 152: more than 150 samples"):
        load_trace(p)


def test_non_utf8_csv_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "l1.csv"
    p.write_bytes((b"time_s,position_m,force_N,bemerkung\n") + "0,0,0,für\n".encode("latin-1"))
    with pytest.raises(TraceError, match=r"l1\.csv: not a text file"):
        load_trace(p)


def test_plausible_trace_does_not_warn(tmp_path: Path) -> None:
    p = _csv(tmp_path, "time_s,position_m,force_N\n" + _good_rows() + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_trace(p)


def test_mapping_with_scale(tmp_path: Path) -> None:
    n = 120
    t = np.arange(n) * 1e-3
    rows = "\n".join(f"{a},{1e3 * a},{2 * a}" for a in t)
    p = _csv(tmp_path, "zeit,pos_mm,strom\n" + rows + "\n")
    mapping = parse_mapping(["time_s=zeit", "position_m=pos_mm*0.001", "force_N=strom*25"], "cli")
    trace = load_trace(p, mapping)
    np.testing.assert_allclose(trace.position_m, t, atol=1e-15)
    np.testing.assert_allclose(trace.force_N, 50 * t, atol=1e-12)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("position_m", "must read COLUMN=EXPRESSION"),
        ("speed=v", "unknown column 'speed'"),
        ("force_N=a\x00", "printable characters"),
        ("force_N=" + "a*" * 200 + "a", "printable characters"),
        ("force_N=a,force_N=b", "column force_N is mapped twice"),
    ],
)
def test_bad_mapping_entries(entry: str, message: str) -> None:
    with pytest.raises(TraceError, match=message):
        parse_mapping(entry.split(","), "cli")


@pytest.mark.parametrize(
    ("expr", "message"),
    [
        ("__import__('os')", "'__import__' is neither a column name nor a number"),
        ("c*1e999", "number 1e999 is not finite"),
        ("c/0", "division by zero"),
        ("(c", "a parenthesis is not closed"),
        ("c c", "unexpected 'c' after a complete term"),
        ("2*3", "names no column"),
    ],
)
def test_bad_mapping_expressions_are_refused_when_the_file_is_read(
    tmp_path: Path, expr: str, message: str
) -> None:
    p = _csv(tmp_path, "a,b,c\n" + _good_rows() + "\n")
    mapping = {"time_s": "a", "position_m": "b", "force_N": expr}
    with pytest.raises(TraceError, match=f"t\\.csv: --map force_N=.*{re.escape(message)}"):
        load_trace(p, mapping)


def test_mapping_to_absent_source(tmp_path: Path) -> None:
    p = _csv(tmp_path, "a,b,c\n" + _good_rows() + "\n")
    with pytest.raises(
        TraceError, match=r"--map force_N=d: 'd' is neither a column name nor a number"
    ):
        load_trace(p, {"time_s": "a", "position_m": "b", "force_N": "d"})


def test_mat_needs_mapping_unless_emps(tmp_path: Path) -> None:
    n = 200
    t = np.arange(n) * 1e-3
    p = tmp_path / "m.mat"
    scipy.io.savemat(p, {"tt": t[:, None], "x": np.sin(t)[:, None], "f": np.cos(9 * t)[:, None]})
    with pytest.raises(TraceError, match=r"not an EMPS record \(missing variables"):
        load_trace(p)
    trace = load_trace(p, {"time_s": "tt", "position_m": "x", "force_N": "f"})
    np.testing.assert_allclose(trace.force_N, np.cos(9 * t))


def test_emps_shaped_mat_is_recognised(tmp_path: Path) -> None:
    n = 300
    t = np.arange(n) * 1e-3
    vir = np.sin(5 * t)
    p = tmp_path / "e.mat"
    scipy.io.savemat(
        p,
        {"t": t[:, None], "qm": 0.1 * t[:, None], "vir": vir[:, None], "gtau": np.array([[35.0]])},
    )
    trace = load_trace(p)
    assert trace.force_kind == "drive"
    np.testing.assert_allclose(trace.force_N, 35.0 * vir)
    assert trace.reference_position_m is None


def test_garbage_mat_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "bad.mat"
    p.write_bytes(b"\x00\x01 this is not matlab" * 10)
    with pytest.raises(TraceError, match=r"bad\.mat"):
        load_trace(p)


@needs_emps
def test_emps_file_values() -> None:
    """Facts from PROVENANCE.md: 24841 samples, 1 ms, force = gtau*vir, gtau = 35.1507 N/V."""
    trace = load_trace(EMPS / "DATA_EMPS.mat")
    assert len(trace) == 24841
    assert trace.force_kind == "drive"
    assert trace.sample_time_s == pytest.approx(1e-3, rel=1e-6)
    raw = scipy.io.loadmat(str(EMPS / "DATA_EMPS.mat"))
    np.testing.assert_allclose(trace.force_N, 35.15065188248547 * raw["vir"].ravel())
    assert trace.reference_position_m is not None
    assert np.ptp(trace.position_m) == pytest.approx(0.2464, abs=1e-3)


@settings(max_examples=25, deadline=None)
@given(
    st.lists(st.floats(min_value=-1e3, max_value=1e3, allow_nan=False), min_size=100, max_size=140)
)
def test_csv_round_trip_any_force(tmp_path_factory: pytest.TempPathFactory, f: list[float]) -> None:
    f = [*f[:-2], -1.0, 1.0]  # a force that varies as a guide's friction does
    n = len(f)
    trace = Trace(
        source="mem",
        time_s=np.arange(n) * 1e-3,
        position_m=np.linspace(0.0, 1e-3, n),
        force_N=np.array(f),
    )
    p = tmp_path_factory.mktemp("rt") / "h.csv"
    write_trace(p, trace)
    np.testing.assert_allclose(load_trace(p).force_N, trace.force_N, rtol=1e-11, atol=1e-300)


@pytest.mark.parametrize(
    "rows",
    [
        "0,0,1\n0.001,1e-6,2\n0.002,2e-6,3\n",  # plain
        "0, 0 ,1\r\n0.001,1e-6, 2\r\n0.002,2e-6,3",  # spaces, CRLF, no final newline
        '0,0,1\n0.001,"1e-6",2\n0.002,2e-6,3\n',  # a quoted cell
        "0,0,1\n\n0.001,1e-6,2\n  \n0.002,2e-6,3\n",  # blank rows
    ],
)
def test_csv_read_in_one_pass_as_cell_by_cell(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, rows: str
) -> None:
    """The one-pass numpy reading of plain files gives the values and row numbers of the
    cell-by-cell reader, and files it cannot read plainly go to that reader."""
    p = _csv(tmp_path, "time_s,position_m,force_N\n" + rows)
    fast = trace_csv.read_csv(p)
    monkeypatch.setattr(trace_csv, "_plain_csv", lambda *args: None)
    cells = trace_csv.read_csv(p)
    assert fast[1] == cells[1]
    assert fast[0].keys() == cells[0].keys()
    for name, values in cells[0].items():
        np.testing.assert_array_equal(fast[0][name], values)
    assert cells[1] == ([2, 3, 4] if "\n\n" not in rows else [2, 4, 6])


def test_a_recorded_trace_is_read_back_as_a_drive_force_from_its_sidecar(
    tmp_path: Path,
) -> None:
    """`gms-comp record` writes a drive force (current times k_f, inertia in it): its
    sidecar says so, and `diagnose` then fits the moving mass without --force-kind."""
    from firmware_bridge.profiles.cia402.recorder import Recording
    from firmware_bridge.settings import CanConfig
    from gms_comp.app.live.recording import to_trace, write_recording
    from sim.plant import PlantConfig

    t = np.arange(600) * 1e-3
    x = 1e-3 * np.sin(2 * np.pi * t)
    v = 2e-3 * np.pi * np.cos(2 * np.pi * t)
    rows = [(float(a), float(a), float(b), 0.1 * float(np.sign(b)))
            for a, b in zip(x, v, strict=True)]  # fmt: skip
    recording = Recording(1e-9, 2.0, rows=rows, slots=list(range(len(rows))))
    path = tmp_path / "rec.csv"
    write_recording(to_trace(recording, CanConfig(), PlantConfig(), "test"), path)
    assert load_trace(path).force_kind == "drive"
    sidecar = tmp_path / "rec.csv.json"
    for text in ("not json", '{"force_kind": "torque"}', "[1, 2]", " " * (1 << 17)):
        sidecar.write_text(text)  # a sidecar that says nothing this reader knows
        assert load_trace(path).force_kind is None
    sidecar.unlink()
    assert load_trace(path).force_kind is None
