"""`gms-comp config`: docs/config.md matches the code, and the default TOML reads back."""

from __future__ import annotations

import dataclasses
import json
import tomllib
import typing
from pathlib import Path

import pytest

from firmware_bridge.settings import load_can_config
from gms_comp.app.cli import main
from gms_comp.app.commands.config import SECTIONS, all_sections, keys, to_markdown, unit_of
from gms_comp.config import KNOWN_SECTIONS, is_section
from gms_comp.measured.diagnosis.run import DiagnosisConfig, load_diagnosis_config
from gms_comp.physics.config import load_ball_config
from gms_comp.tables.reduction import TableConfig, load_table_config
from sim.scenarios import load_scenario

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "config.md"


def test_one_list_names_every_known_section() -> None:
    assert set(SECTIONS) == KNOWN_SECTIONS


def test_doc_is_generated_from_the_code() -> None:
    assert DOC.read_text(encoding="utf-8") == to_markdown(keys()), (
        "docs/config.md is out of date: run `gms-comp config --markdown -o docs/config.md`"
    )


def test_doc_lists_every_key_of_every_section() -> None:
    text = DOC.read_text(encoding="utf-8")
    for section, cls in all_sections():
        assert f"## [{section}]" in text
        part = text.split(f"## [{section}]")[1].split("\n## ")[0]
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if is_section(hints[f.name]):  # its own ## [section.sub]
                continue
            assert f"| `{f.name}` |" in part, f"{section}.{f.name} missing from docs/config.md"
            if f.metadata.get("why"):  # the why of a key that has one is in its row
                assert f.metadata["why"] in part, f"{section}.{f.name}: its why"


@pytest.mark.parametrize(
    ("name", "unit"),
    [
        ("ball_radius_m", "m"),
        ("youngs_modulus_ball_Pa", "Pa"),
        ("feed_m_s", "m/s"),
        ("servo_rate_Hz", "Hz"),
        ("rate_limit_A_per_s", "A/s"),
        ("adaptation_rate_per_s", "1/s"),
        ("force_constant_N_per_A", "N/A"),
        ("bitrate_bit_s", "bit/s"),
        ("rx_timeout_s", "s"),
        ("ball_loads_N", "N"),
        ("moving_mass_kg", "kg"),
        ("lambda_min", ""),  # a ratio, not minutes
        ("significance_t", ""),
        ("poisson_ratio_ball", ""),
    ],
)
def test_unit_from_the_name_suffix(name: str, unit: str) -> None:
    assert unit_of(name) == unit


def test_rows_state_unit_default_and_range() -> None:
    text = DOC.read_text(encoding="utf-8")
    # The seed's Table 1 values and the loader's ranges, written out by hand.
    assert (
        "| `ball_radius_m` | m | *required* (Table 1: `0.003175`) | number, in [0.0001, 0.05] |"
        in text
    )
    assert (
        "| `poisson_ratio_ball` | - | *required* (Table 1: `0.3`) | number, in [0, 0.5) |" in text
    )
    assert "| `slip_exaggeration` | - | `1.0` (Table 1: `1.2`) | number, in [1, 10] |" in text
    assert '| `curve` | - | `"virgin"` | one of "virgin", "reversal" |' in text
    assert "| `elements` | - | `16` |" in text and "in [1, 1024]" in text


@pytest.fixture(scope="module")
def defaults_toml(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("config") / "defaults.toml"
    assert main(["config", "--defaults", "-o", str(path)]) == 0
    return path


def test_defaults_name_every_section_and_key(defaults_toml: Path) -> None:
    doc = tomllib.loads(defaults_toml.read_text(encoding="utf-8"))
    assert set(doc) == KNOWN_SECTIONS
    for section, cls in SECTIONS.items():
        # An empty array (no load family) has no TOML form the loader takes: it is a comment.
        expected = {f.name for f in dataclasses.fields(cls)} - {"family_loads_N"}
        assert set(doc[section]) == expected, section
    assert doc["bearing"]["ball_radius_m"] == 3.175e-3  # seed Table 1
    assert doc["bearing"]["slip_exaggeration"] == 1.2  # Table 1's C_v, not the dataclass 1.0
    assert "# family_loads_N = [" in defaults_toml.read_text(encoding="utf-8")


def test_defaults_read_back_by_every_loader(defaults_toml: Path) -> None:
    """Every command's loader takes the file and gets the same values as without a config."""
    ball, default_ball = load_ball_config(defaults_toml), load_ball_config()
    assert dataclasses.replace(ball, path="") == dataclasses.replace(default_ball, path="")
    assert load_table_config(defaults_toml) == TableConfig()
    scenario, default_scenario = load_scenario(defaults_toml), load_scenario()
    for name in ("plant", "controller", "scenario", "compensator"):
        assert getattr(scenario, name) == getattr(default_scenario, name), name
    assert load_can_config(defaults_toml) == load_can_config()
    assert load_diagnosis_config(defaults_toml) == DiagnosisConfig()


def test_model_gives_the_same_numbers_from_the_defaults_file(
    defaults_toml: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["model", "--json"]) == 0
    implicit = json.loads(capsys.readouterr().out)
    assert main(["model", str(defaults_toml), "--json"]) == 0
    explicit = json.loads(capsys.readouterr().out)
    implicit.pop("config"), explicit.pop("config")
    assert implicit == explicit


def test_check_summary_and_json(defaults_toml: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", str(defaults_toml)]) == 0
    out = capsys.readouterr().out
    assert f"valid; {len(SECTIONS)} sections" in out
    assert main(["config", str(defaults_toml), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["sections"]["plant"]["moving_mass_kg"] == 30.0
    assert data["sections"]["stand"]["ball_loads_N"] == [50.0, 50.0, 50.0, 50.0]


def test_bad_value_is_one_line_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.toml"
    text = (ROOT / "configs" / "table1.toml").read_text(encoding="utf-8")
    path.write_text(text + "\n[plant]\nmoving_mass_kg = -1.0\n", encoding="utf-8")
    assert main(["config", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "plant.moving_mass_kg" in err


def test_output_written_and_announced_on_stderr_under_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "config.md"
    assert main(["config", "--markdown", "-o", str(out), "--json"]) == 0
    captured = capsys.readouterr()
    json.loads(captured.out)  # stdout holds the JSON only
    assert captured.err.strip() == f"wrote {out}"
    assert out.read_text(encoding="utf-8") == DOC.read_text(encoding="utf-8")


def test_output_into_a_missing_folder_is_refused_at_parsing(tmp_path: Path) -> None:
    assert main(["config", "--defaults", "-o", str(tmp_path / "missing" / "x.toml")]) == 2
