"""Frame layouts, scaling, bus load and config of the CAN feedforward."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
from cantools.autosar import check_profile5_crc
from hypothesis import given
from hypothesis import strategies as st

from firmware_bridge.busload import bus_load, check_bus_load, frame_bits_worst_case
from firmware_bridge.freshness import Command, Mode
from firmware_bridge.profiles.cia402.codec import Cia402Codec, load_drive_od
from firmware_bridge.profiles.e2e.codec import E2eCodec
from firmware_bridge.settings import CanConfig, load_can_config
from firmware_bridge.streamer import Shaper, make_tx, profile_bus_load
from gms_comp.errors import BusError, ConfigError


def test_worst_case_frame_is_135_bits() -> None:
    assert frame_bits_worst_case(8) == 135  # the spec's figure for an 8-byte classic frame
    assert 1e6 / frame_bits_worst_case(8) == pytest.approx(7407, abs=1)


def test_bus_load_of_one_8_byte_frame_per_ms_is_13_5_percent() -> None:
    assert bus_load([(8, 1000.0)], 1_000_000) == pytest.approx(0.135)


def test_bus_load_above_70_percent_is_refused() -> None:
    check_bus_load(0.70)
    with pytest.raises(BusError, match="70"):
        check_bus_load(0.7001)


def test_e2e_at_2_5_kHz_fits_alone_but_not_with_background_traffic() -> None:
    fast = replace(CanConfig(), profile="e2e", cycle_period_s=1 / 2500)
    assert profile_bus_load(fast, make_tx(fast)) == pytest.approx(2 * 2500 * 135 / 1e6)
    crowded = replace(fast, background_load=0.2)
    assert profile_bus_load(crowded, make_tx(crowded)) > 0.7


def test_cia402_scaling_is_per_mille_of_rated_current() -> None:
    codec = Cia402Codec(CanConfig(rated_current_A=2.0), load_drive_od(1))
    assert codec.to_raw(0.5) == 250
    # 0x60B2 INTEGER16 little-endian, the drive cycle 0x2001 (UNSIGNED16, modulo 2**16),
    # the session 0x2003 and the mode 0x2004 (one byte each)
    data = codec.rpdo_frame(-250, 65536 + 258, 7, Mode.REQUEST).data
    assert data == (-250).to_bytes(2, "little", signed=True) + b"\x02\x01" + b"\x07\x01"
    assert codec.unpack_rpdo(bytes(data)) == Command(258, -250, 7, Mode.REQUEST)
    assert codec.rpdo_cob_id == 0x301 and codec.sync_cob_id == 0x80
    assert codec.nc_cob_id == 0x201 and codec.status_cob_id == 0x181


@pytest.mark.parametrize(
    "data", [b"\x00\x00\x01\x00\x00\x00", b"\x00\x00\x01\x00\x07\x04", b"\x00" * 5]
)
def test_cia402_rpdo_without_session_bad_mode_or_length_is_refused(data: bytes) -> None:
    assert Cia402Codec.unpack_rpdo(data) is None


def test_eds_rpdo_must_map_torque_offset(tmp_path: Path) -> None:
    from firmware_bridge.profiles.cia402.codec import default_eds_path

    bad = tmp_path / "bad.eds"
    bad.write_text(default_eds_path().read_text().replace("0x60B20010", "0x60710010"))
    with pytest.raises(BusError, match="0x60B2"):
        Cia402Codec(CanConfig(), load_drive_od(1, bad))


@given(
    st.integers(0, 2**16 - 1),
    st.integers(-32767, 32767),
    st.integers(1, 255),
    st.sampled_from(list(Mode)),
)
def test_e2e_command_round_trip_and_crc(cycle: int, raw: int, session: int, mode: Mode) -> None:
    codec = E2eCodec()
    data = codec.encode_command(cycle, raw, session, mode)
    assert len(data) == 8
    assert check_profile5_crc(data, codec.command_data_id)
    assert codec.check_command(data) == Command(cycle, raw, session, mode)


@given(st.integers(0, 63), st.integers(0, 2**16 - 1))
def test_any_single_bit_flip_is_detected(bit: int, cycle: int) -> None:
    codec = E2eCodec()
    data = bytearray(codec.encode_command(cycle, 1234, 9, Mode.COMMAND))
    data[bit // 8] ^= 1 << (bit % 8)
    assert codec.check_command(bytes(data)) is None


def test_e2e_scaling_is_0_1_mA_from_the_dbc() -> None:
    codec = E2eCodec()
    assert codec.to_raw(1.2345) == 12345
    assert codec.limit_raw == 32767


def test_encoding_out_of_range_is_refused_by_cantools_strict() -> None:
    from cantools.database.errors import EncodeError

    with pytest.raises(EncodeError):
        E2eCodec().encode_command(0, 40000, 1, Mode.COMMAND)


@given(st.floats(-100, 100, allow_nan=False))
def test_shaper_saturates_before_encoding(current_A: float) -> None:
    cfg = replace(CanConfig(), profile="e2e", max_current_A=1.0)
    tx = make_tx(cfg)
    raw = Shaper(tx.limit_raw, cfg.ramp_cycles).step(tx.to_raw(current_A))
    assert abs(raw) <= 10000  # 1 A in 0.1 mA
    tx.claim.time.observe(0, tx.claim.session, 0.0)
    assert tx.feedforward(Mode.COMMAND, raw, 0.0) is not None  # strict=True did not raise


def test_shaper_ramps_to_zero_within_ramp_time_without_jumps() -> None:
    cfg = CanConfig(max_current_A=1.0, ramp_time_s=5e-3, cycle_period_s=1e-3)
    shaper = Shaper(limit_raw=500, ramp_cycles=cfg.ramp_cycles)
    shaper.step(-500)
    ramp = [shaper.step(None) for _ in range(cfg.ramp_cycles)]
    assert ramp[-1] == 0
    assert all(abs(b - a) <= 100 for a, b in zip([-500, *ramp], ramp, strict=False))


def test_can_section_errors_name_file_and_key(tmp_path: Path) -> None:
    bad = tmp_path / "c.toml"
    bad.write_text("[can]\nprofile = 'j1939'\n")
    with pytest.raises(ConfigError, match=r"c\.toml: can\.profile"):
        load_can_config(bad)
    bad.write_text("[can]\ncycle_period_s = 1e-3\nrx_timeout_s = 1e-4\n")
    with pytest.raises(ConfigError, match="rx_timeout_s"):
        load_can_config(bad)


def test_default_config_loads_and_fallback_is_timeout_plus_ramp() -> None:
    cfg = load_can_config()
    assert cfg.fallback_time_s == pytest.approx(cfg.rx_timeout_s + cfg.ramp_time_s)


def test_packaged_data_files_are_found_through_importlib_resources() -> None:
    from firmware_bridge.resources import packaged_path

    for name in ("gms_ff.dbc", "cia402_drive.eds", "c/ff_handler.c", "c/ff_handler.h"):
        assert packaged_path(name).is_file()
    with pytest.raises(BusError, match="not found"):
        packaged_path("missing.dbc")
