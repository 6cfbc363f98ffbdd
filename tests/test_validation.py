"""The validation layer's building blocks: one error type and format, bounded reading."""

from __future__ import annotations

from pathlib import Path

import pytest

from gms_comp.errors import ConfigError, GmsCompError, InputError, TableError, TraceError
from gms_comp.validation import (
    MAX_NESTING_DEPTH,
    decode_utf8,
    nesting_depth,
    parse_json,
    read_text,
    read_toml_document,
)


def test_one_error_type_and_one_format() -> None:
    for cls in (ConfigError, TableError, TraceError):
        assert issubclass(cls, InputError) and issubclass(cls, GmsCompError)
        err = cls("a.toml", "stand.ball_loads_N[2]", "must be\nin [0.001, 100000]")
        assert str(err) == "a.toml: stand.ball_loads_N[2]: must be in [0.001, 100000]"
    assert str(TableError("t.json: whole message")) == "t.json: whole message"
    assert (
        str(InputError("--workers", "", "must be in [1, 256]")) == "--workers: must be in [1, 256]"
    )


@pytest.mark.parametrize(
    ("text", "depth"),
    [
        ("a = [[1], [2]]", 2),
        ('a = "[[[["', 0),
        ("a = '[[{'", 0),
        ('a = "x\\\\"\nb = [[1]]', 2),  # an escaped backslash ends the string before [[
        ('a = "x\\"[[["', 0),  # an escaped quote does not
        ("# [[[[\nb = [1]", 1),
        ('{"k": [1, {"j": "}"}]}', 3),
    ],
)
def test_nesting_depth_ignores_strings_and_comments(text: str, depth: int) -> None:
    assert nesting_depth(text) == depth


def test_deep_json_is_refused_before_the_parser_recurses() -> None:
    deep = "[" * (MAX_NESTING_DEPTH + 1) + "]" * (MAX_NESTING_DEPTH + 1)
    with pytest.raises(InputError, match=f"nested {MAX_NESTING_DEPTH + 1} deep"):
        parse_json(deep, "t.json")
    at_cap = parse_json("[" * MAX_NESTING_DEPTH + "]" * MAX_NESTING_DEPTH, "t.json")
    assert isinstance(at_cap, list)
    with pytest.raises(InputError, match="NaN is not allowed"):
        parse_json('{"a": NaN}', "t.json")


def test_non_utf8_bytes_are_reported_with_their_line() -> None:
    data = b"a = 1\nb = 2\nc = '\xe9'\n"
    with pytest.raises(InputError, match=r"^x\.toml: line 3: byte 0xe9 is not UTF-8 text$"):
        decode_utf8(data, "x.toml")


def test_read_text_checks_size_and_kind(tmp_path: Path) -> None:
    big = tmp_path / "big.toml"
    big.write_text("#" * 101)
    with pytest.raises(InputError, match="101 bytes, more than the 100"):
        read_text(big, max_bytes=100)
    with pytest.raises(InputError, match="is not a file"):
        read_text(tmp_path, max_bytes=100)
    with pytest.raises(ConfigError, match="file not found"):
        read_toml_document(tmp_path / "none.toml")
