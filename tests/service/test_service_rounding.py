"""The answer's value lists: ``finite_list`` rounds exactly as formatting each value does."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from skisnow.app.service.rounding import finite_list


def _by_text(a, scale=1.0, digits=6):
    """The reference: each value scaled and formatted; ``None`` where the scaled value is not
    finite (the former code checked before scaling, so 1.7e308 × 1e3 gave inf, which the JSON
    encoder refuses)."""
    out = []
    for v in a:
        s = float(v) * scale
        out.append(float(f"{s:.{digits}g}") if math.isfinite(s) else None)
    return out


def _same(x, y):
    if x is None or y is None:
        return x is None and y is None
    return type(x) is float and x == y and math.copysign(1, x) == math.copysign(1, y)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=1, max_size=50),
    st.sampled_from([1.0, 1e3, 1e-3, 1e6, 1e-6, 1e-9]),
    st.sampled_from([4, 6]),
)
def test_matches_formatting_every_value(values, scale, digits):
    a = np.array(values, dtype=float)
    with np.errstate(over="ignore"):
        expected = _by_text(a, scale, digits)
        got = finite_list(a, scale, digits)
    assert len(got) == len(expected)
    assert all(_same(x, y) for x, y in zip(got, expected, strict=True))


def test_ties_powers_of_ten_signs_and_extremes():
    rng = np.random.default_rng(4)
    powers = 10.0 ** np.arange(-30, 31)
    edge = np.concatenate(
        [
            powers,
            np.nextafter(powers, 0),
            np.nextafter(powers, np.inf),
            -powers,
            np.round(rng.lognormal(0, 3, 400), 3) + 0.0005,  # decimal ties at the 7th digit
            np.array([123456.5, 1234565.0, 0.1234565, 999999.5, 9999995.0, 5e-324, 1.7e308]),
            np.array([0.0, -0.0, np.nan, np.inf, -np.inf]),
        ]
    )
    for scale in (1.0, 1e3, 1e-3):
        for digits in (4, 6):
            with np.errstate(over="ignore"):
                expected = _by_text(edge, scale, digits)
                got = finite_list(edge, scale, digits)
            bad = [
                (v, x, y) for v, x, y in zip(edge, expected, got, strict=True) if not _same(x, y)
            ]
            assert not bad, bad[:5]


@pytest.mark.parametrize("shape", [(0,), (7,)])
def test_empty_and_plain_lists(shape):
    a = np.linspace(0.1, 2.0, shape[0])
    assert finite_list(a, 1e3) == _by_text(a, 1e3)
    assert finite_list(list(a)) == _by_text(a)
