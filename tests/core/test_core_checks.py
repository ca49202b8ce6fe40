"""The shared range checks of exobench.core: what they accept and refuse, and what they say."""

import pytest

from exobench.core import ConfigError, check_int


@pytest.mark.parametrize("value, expected", [(3, 3), ("4", 4), (5.0, 5), (1, 1)])
def test_check_int_accepts_whole_numbers_in_range(value, expected):
    got = check_int("pipe.n", value, 1, 5)
    assert got == expected and type(got) is int


@pytest.mark.parametrize("value", [True, "x", float("nan"), float("inf"), "inf", 2.5, 0, 6, None, 1e308])
def test_check_int_refuses_with_field_value_and_range(value):
    with pytest.raises(ConfigError) as e:
        check_int("pipe.n", value, 1, 5)
    assert e.value.field == "pipe.n" and "[1, 5]" in str(e.value)


def test_check_int_open_bounds():
    assert check_int("k", 10**6, low=1) == 10**6
    assert check_int("k", -3, high=0) == -3
    with pytest.raises(ConfigError, match=">= 1"):
        check_int("k", 0, low=1)
