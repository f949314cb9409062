import math

import pytest

from repertoire.criteria import Bound, evaluate_criteria
from repertoire.errors import RepertoireError
from repertoire.limits import ResourceLimitError, format_bytes, require_memory


def test_evaluate_criteria_pass_fail_missing_and_nan():
    results = evaluate_criteria(
        {"a": 0.5, "b": math.nan, "d": 2.0},
        {"a": Bound(0, 1), "b": Bound(hi=1), "c": Bound(lo=0), "d": Bound(hi=1.5)},
    )
    assert [r.passed for r in results] == [True, False, False, False]
    assert results[0].reason == ""
    assert results[1].reason == "b = nan, expected <= 1"
    assert results[2].reason == "c was not reported"
    assert results[3].reason == "d = 2, expected <= 1.5"


def test_bound_edges_are_inclusive_and_bad_bounds_refused():
    (r,) = evaluate_criteria({"x": 1.0}, {"x": Bound(1.0, 1.0)})
    assert r.passed
    assert Bound(lo=2).describe() == ">= 2"
    with pytest.raises(ValueError, match="needs lo, hi or both"):
        Bound()
    with pytest.raises(ValueError, match="lo=2 is above hi=1"):
        Bound(2, 1)


def test_require_memory_refuses_with_the_figure(monkeypatch):
    require_memory(1024, "small grid", limit_bytes=2048)
    with pytest.raises(ResourceLimitError, match=r"big grid would need about 3\.0 KiB, over"):
        require_memory(3 * 1024, "big grid", limit_bytes=2048)
    assert issubclass(ResourceLimitError, RepertoireError)
    monkeypatch.setenv("REPERTOIRE_MAX_MEMORY_BYTES", "100")
    with pytest.raises(ResourceLimitError, match="over the 100 B limit"):
        require_memory(101, "grid")
    monkeypatch.setenv("REPERTOIRE_MAX_MEMORY_BYTES", "lots")
    with pytest.raises(ResourceLimitError, match="not a whole number"):
        require_memory(1, "grid")


def test_format_bytes():
    assert format_bytes(512) == "512 B"
    assert format_bytes(1536) == "1.5 KiB"
    assert format_bytes(3 * 1024**3) == "3.0 GiB"
