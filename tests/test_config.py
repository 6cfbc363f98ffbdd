"""Every bad physics config is refused by `gms-comp model` with one line and exit code 2."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from gms_comp.app.cli import main
from gms_comp.config import default_config_path
from gms_comp.physics.config import load_ball_config

DEFAULT = default_config_path().read_text()


def _edit(text: str, key: str, value: str) -> str:
    """Replace the value of ``key = ...`` (first occurrence) in a TOML text."""
    pattern = re.compile(rf"^{re.escape(key)}\s*=.*$", re.MULTILINE)
    assert pattern.search(text), key
    return pattern.sub(f"{key} = {value}", text, count=1)


def _drop(text: str, key: str) -> str:
    return re.sub(rf"^{re.escape(key)}\s*=.*\n", "", text, count=1, flags=re.MULTILINE)


# Ranges and types of every key are drawn by tests/test_schema_configs.py; these are the
# refusals that need more than one key (the groove against the ball, the lambda range) and
# one range refusal as the CLI prints it.
BAD_VALUES = [
    ("raceway_radius_m", "3.175e-3", "bearing.raceway_radius_m", "wider than the ball"),
    ("raceway_radius_m", "3.0e-3", "bearing.raceway_radius_m", "wider than the ball"),
    ("raceway_radius_m", "3.18e-3", "bearing.raceway_radius_m", "wider than the ball"),
    ("ball_radius_m", "0.0", "bearing.ball_radius_m", "must be in [0.0001, 0.05]"),
    ("lambda_max", "1.0", "model.lambda_max", "must be > lambda_min"),
]


def _run_bad(tmp_path: Path, text: str, capsys: pytest.CaptureFixture[str]) -> tuple[Path, str]:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["model", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return path, lines[0]


@pytest.mark.parametrize(("key", "value", "where", "reason"), BAD_VALUES)
def test_bad_value_is_refused(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    key: str,
    value: str,
    where: str,
    reason: str,
) -> None:
    path, line = _run_bad(tmp_path, _edit(DEFAULT, key, value), capsys)
    assert str(path) in line
    assert where in line
    assert reason in line


@pytest.mark.parametrize(
    "key", ["ball_radius_m", "raceway_radius_m", "youngs_modulus_ball_Pa", "ball_loads_N"]
)
def test_missing_key_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str
) -> None:
    path, line = _run_bad(tmp_path, _drop(DEFAULT, key), capsys)
    assert str(path) in line and key in line and "missing required key" in line


def test_unknown_key_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = DEFAULT.replace("[bearing]\n", "[bearing]\nball_radius_mm = 3.175\n")
    path, line = _run_bad(tmp_path, text, capsys)
    assert str(path) in line and "bearing.ball_radius_mm" in line and "unknown key" in line


def test_unknown_section_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, line = _run_bad(tmp_path, DEFAULT + "\n[bearings]\nx = 1\n", capsys)
    assert str(path) in line and "bearings" in line and "unknown section" in line


@pytest.mark.parametrize("text", ["[bearing\nball_radius_m = 1", "ball_radius_m = = 3"])
def test_unreadable_toml_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    path, line = _run_bad(tmp_path, text, capsys)
    assert str(path) in line and "not valid TOML" in line


def test_missing_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", str(tmp_path / "nope.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "nope.toml" in err and "file not found" in err


def test_model_section_is_optional(tmp_path: Path) -> None:
    text = DEFAULT.split("[model]")[0]
    path = tmp_path / "no_model.toml"
    path.write_text(text)
    cfg = load_ball_config(path)
    assert cfg.model.tangential_stiffness == "seed"


def test_default_is_table1() -> None:
    cfg = load_ball_config()
    assert cfg.bearing.ball_radius_m == 3.175e-3
    assert cfg.bearing.raceway_radius_m == 3.5e-3
    assert cfg.stand.ball_loads_N == (50.0,) * 4
    assert cfg.bearing.slip_exaggeration == 1.2
    assert cfg.stand.rolling_distance_per_travel == 0.5


def test_binary_config_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, line = _run_bad(tmp_path, "\x00\x01binary", capsys)
    assert str(path) in line and "NUL character" in line


def test_non_utf8_config_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes(DEFAULT.encode() + "# Lager für Kugeln\n".encode("latin-1"))
    assert main(["model", str(path)]) == 2
    line = capsys.readouterr().err.strip()
    lines = DEFAULT.count("\n") + 1
    assert str(path) in line and f"line {lines}" in line and "0xfc is not UTF-8" in line


def test_deeply_nested_array_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    deep = "[" * 5000 + "]" * 5000
    path, line = _run_bad(tmp_path, DEFAULT + f"\n[table]\nfamily_loads_N = {deep}\n", capsys)
    assert str(path) in line and "nested 5000 deep" in line


def test_too_many_ball_loads_are_refused_by_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    loads = ", ".join(["50.0"] * 200_000)
    _, line = _run_bad(tmp_path, _edit(DEFAULT, "ball_loads_N", f"[{loads}]"), capsys)
    assert "stand.ball_loads_N" in line and "200000 entries, more than the 1024" in line


def test_oversized_config_is_refused_before_parsing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, line = _run_bad(tmp_path, DEFAULT + "#" * (5 << 20), capsys)
    assert str(path) in line and "bytes, more than the 4194304" in line


@pytest.mark.parametrize(("load", "modulus"), [("1e5", "210e9"), ("2e4", "1e9"), ("1e3", "1e8")])
def test_contact_wider_than_the_model_allows_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], load: str, modulus: str
) -> None:
    """Loads and moduli each inside their ranges, but together they would press a contact
    ellipse wider than half the ball: refused at the edge of the Hertz model."""
    text = _edit(DEFAULT, "ball_loads_N", f"[{load}]")
    text = _edit(text, "youngs_modulus_ball_Pa", modulus)
    text = _edit(text, "youngs_modulus_raceway_Pa", modulus)
    path, line = _run_bad(tmp_path, text, capsys)
    assert str(path) in line and "stand.ball_loads_N" in line
    assert "contact ellipse" in line and "outside the Hertz model" in line


@pytest.mark.parametrize(
    ("text", "key", "reason"),
    [
        (
            "[diagnosis.selection]\nmargin = 2.0\n",
            "diagnosis.selection.margin",
            "must be in [0, 1]",
        ),
        ("[diagnosis]\nselection = 3\n", "diagnosis.selection", "must be a [section] table"),
        ("[diagnosis.intervals]\nlevl = 0.9\n", "diagnosis.intervals.levl", "unknown key"),
    ],
)
def test_a_sub_section_is_read_and_refused_by_its_dotted_key(
    tmp_path: Path, text: str, key: str, reason: str
) -> None:
    from gms_comp.errors import ConfigError
    from gms_comp.measured.diagnosis.config import load_diagnosis_config

    good = tmp_path / "good.toml"
    good.write_text("[diagnosis]\nn_blocks = 30\n[diagnosis.selection]\nmargin = 0.1\n")
    cfg = load_diagnosis_config(good)
    assert cfg.n_blocks == 30 and cfg.selection.margin == 0.1
    assert cfg.selection.small_margin == 0.01  # the rest at their defaults
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(key) + ".*" + re.escape(reason)):
        load_diagnosis_config(bad)
