"""The JSON readers keep their own error types and messages: intrinsics and dataset cameras raise
InputError, a result file FileNotFoundError (missing) or ValueError (not JSON); each names the file."""

from __future__ import annotations

import pytest

from cuboidcli.io.depth import InputError, parse_intrinsics
from cuboidcli.io.jsonfile import read_json
from cuboidcli.io.result import read_result


def test_read_json_parses_and_names_the_file(tmp_path):
    good, bad = tmp_path / "good.json", tmp_path / "bad.json"
    good.write_text('{"a": [1, 2]}', encoding="utf-8")
    bad.write_text('{"a": ', encoding="utf-8")
    assert read_json(good, ValueError, "{path} broken") == {"a": [1, 2]}
    with pytest.raises(ValueError, match=r"bad\.json broken at line 1"):
        read_json(bad, ValueError, "{path} broken at line {e.lineno}")
    with pytest.raises(KeyError, match="nope.json gone"):
        read_json(tmp_path / "nope.json", ValueError, "{path}", missing="{path} gone", missing_error=KeyError)
    with pytest.raises(ValueError, match="nope.json gone"):
        read_json(tmp_path / "nope.json", ValueError, "{path}", missing="{path} gone")


def test_callers_keep_their_errors(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("not json", encoding="utf-8")
    with pytest.raises(InputError, match=r"intrinsics file .*bad\.json is not valid JSON \(.* at line 1\)"):
        parse_intrinsics(str(bad))
    with pytest.raises(InputError, match="intrinsics file not found: .*nope.json"):
        parse_intrinsics(str(tmp_path / "nope.json"))
    with pytest.raises(ValueError, match=r"bad\.json is not valid JSON: Expecting value: line 1"):
        read_result(bad)
    with pytest.raises(FileNotFoundError, match="result file not found: .*nope.json"):
        read_result(tmp_path / "nope.json")
