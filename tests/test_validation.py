"""``manifold.validation.check_real``: what it accepts, what it refuses and what its message says."""

import math
import re
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from manifold.validation import check_real

finite = st.floats(allow_nan=False, allow_infinity=False)
reals = st.one_of(
    finite,
    st.integers(-(2**60), 2**60),
    finite.map(np.float64),
    st.floats(width=32, allow_nan=False, allow_infinity=False).map(np.float32),
    st.integers(-(2**62), 2**62).map(np.int64),
    finite.map(np.longdouble),
    finite.map(np.array),  # 0-d arrays
    st.fractions(),
)


def refused(value, match: str | None = None, **kw) -> str:
    with pytest.raises(ValueError) as info:
        check_real("tau", value, **kw)
    message = str(info.value)
    assert message.startswith("tau must be "), message  # names the argument
    assert repr(value) in message  # and the bad value
    if match is not None:
        assert re.search(match, message), message
    return message


@given(reals)
def test_real_numbers_come_back_as_the_same_float(x):
    y = check_real("tau", x)
    assert type(y) is float and y == float(x)


@given(reals)
def test_positive_admits_exactly_the_positive_reals(x):
    if float(x) > 0:
        assert check_real("tau", x, positive=True) == float(x)
    else:
        refused(x, match=r"in \(0, inf\)", positive=True)


@given(reals)
def test_nonzero_admits_exactly_the_nonzero_reals(x):
    if float(x) != 0:
        assert check_real("tau", x, nonzero=True) == float(x)
    else:
        refused(x, match="nonzero", nonzero=True)


@given(st.text())
def test_strings_are_refused_never_converted(s):
    refused(s, match="finite real number.*of type str")


@pytest.mark.parametrize("s", ["1", "1.5", " 2 ", "inf", b"1"])
def test_numeric_strings_are_refused(s):
    refused(s)


@given(st.booleans(), st.sampled_from([bool, np.bool_, np.array]))
def test_bools_are_refused(b, kind):
    refused(kind(b), match="of type")


@given(st.complex_numbers(allow_nan=False, allow_infinity=False), st.sampled_from([complex, np.complex128, np.array]))
def test_complex_numbers_are_refused_even_when_real_valued(z, kind):
    refused(kind(z), match="of type")


@given(st.sampled_from([math.nan, math.inf, -math.inf, np.float32("nan"), np.array(np.inf), 10**400]),
       st.booleans(), st.booleans())
def test_nan_and_infinities_are_refused_with_any_options(x, positive, nonzero):
    refused(x, positive=positive, nonzero=nonzero)


@pytest.mark.parametrize("value", [None, [1.0], (1.0,), np.array([1.0]), np.zeros((1, 1)), object(), Fraction])
def test_non_scalars_are_refused(value):
    refused(value, match="of type")


def test_the_message_states_the_valid_range():
    assert "a finite real number" in refused(math.nan)
    assert "in (0, inf)" in refused(0.0, positive=True)
    assert "in (0, inf)" in refused(-1, positive=True, nonzero=True)
    assert "finite nonzero" in refused(-0.0, nonzero=True)
