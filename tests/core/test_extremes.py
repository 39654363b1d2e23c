"""``parmpm.core.extremes.column_min_max`` gives numpy's axis-0 ``min`` and ``max`` (the
independent result), bit for bit, NaN and infinities included; only the sign of a zero tied
with the other zero is left open, so the drawn values hold one zero sign per array."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from parmpm.core.extremes import column_min_max

VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                   st.sampled_from([0.0, 1e-300, -1e300, 5e-324]))


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 3).flatmap(
    lambda d: arrays(np.float64, st.tuples(st.integers(1, 40), st.just(d)), elements=VALUES)))
def test_the_same_as_numpys_axis_0_reduction(a):
    a = np.where(a == 0.0, 0.0, a)  # one zero sign
    lo, hi = column_min_max(a)
    np.testing.assert_array_equal(lo, a.min(axis=0))
    np.testing.assert_array_equal(hi, a.max(axis=0))
    assert lo.dtype == a.dtype and lo.shape == (a.shape[1],)


def test_a_view_of_a_wider_array_and_integers():
    a = np.arange(30.0).reshape(10, 3)[:, 1:]
    np.testing.assert_array_equal(column_min_max(a)[0], [1.0, 2.0])
    lo, hi = column_min_max(np.array([[3, -2], [1, 7]]))
    assert lo.tolist() == [1, -2] and hi.tolist() == [3, 7]


def test_no_rows_is_numpys_error():
    with pytest.raises(ValueError):
        column_min_max(np.empty((0, 2)))
