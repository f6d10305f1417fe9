"""``"resolution"`` is float arithmetic's collision criterion (issue 42, item 4): a spec in exact or certified
arithmetic, which decides every sign exactly, refuses it naming the field, as it refuses ``"precision"`` outside
certified arithmetic, rather than accept it and ignore it."""

from __future__ import annotations

import pytest
from helpers import HALF_PLANE, assert_input_error, call, spec, write

from pinnedballs.specs import parse_spec


@pytest.mark.parametrize("arithmetic", ["exact", "certified"])
def test_a_resolution_outside_float_arithmetic_is_refused_naming_it(tmp_path, arithmetic):
    data = spec(HALF_PLANE, arithmetic=arithmetic, resolution=1e-9)
    words = f"resolution: is the collision criterion of float arithmetic; this run's is '{arithmetic}'"
    with pytest.raises(ValueError) as caught:
        parse_spec(data).build()
    assert str(caught.value) == words
    path = write(tmp_path / "s.json", data)
    for argv in (["validate", path], ["run", path, "--out", tmp_path / "r", "--quiet"]):
        code, stdout, err = call(*argv)
        assert_input_error(code, err, words)
        assert stdout == "" and not (tmp_path / "r").exists()
    with pytest.raises(ValueError,
                       match=r"^precision: is the precision of certified arithmetic; this run's is 'float'"):
        parse_spec(spec(HALF_PLANE, precision=256)).build()  # the refusal it follows
    assert parse_spec(spec(HALF_PLANE, resolution=1e-9)).build().resolution == 1e-9  # floats keep theirs
