"""Python given what a new user tries (issue #34, item 7): impossible sizes are a MemoryError
before anything is allocated, and values that used to be silently wrong are refused or kept."""

import numpy as np
import pytest

import rootfuse as rf


def test_impossible_channel_count_is_a_memory_error():
    # (2**40, 0, 3) holds no memory but claims 2**40 channels: the interpreter used to abort
    # on an 8.8 TB allocation.
    empty = np.empty((2**40, 0, 3))
    with pytest.raises(MemoryError, match="channels need about 1280 bytes each"):
        rf.run_many("mahony", empty, empty, None, 0.01, dof=6)


def test_bias_is_checked_in_the_filters_precision():
    f = rf.Filter("flagship", precision="f32")
    with pytest.raises(ValueError, match="not representable in this f32 filter"):
        f.set_bias([1e39, 0, 0])
    # The same value is finite in f64, so an f64 filter takes it.
    assert rf.Filter("flagship").set_bias([1e39, 0, 0])


def test_a_bias_set_before_the_first_sample_is_kept():
    f = rf.Filter("flagship")
    assert f.set_bias([0.01, -0.02, 0.005])
    f.update([0.01, -0.02, 0.005], [0, 0, 9.81], [20, 0, -40], dt=0.01)
    np.testing.assert_allclose(f.bias, [0.01, -0.02, 0.005], atol=1e-4)


def test_a_quaternion_far_from_unit_norm_is_refused():
    f = rf.Filter("flagship", precision="f32")
    with pytest.raises(ValueError, match="far from 1"):
        f.set_quat([1e-16, 1e-16, 0, 0])
    f.set_quat([1.001, 0, 0, 0])  # a small deviation is normalised
    np.testing.assert_allclose(f.quat, [1, 0, 0, 0], atol=1e-6)


def test_truth_that_is_no_orientation_and_nan_use_flags_are_refused():
    q = np.tile([1.0, 0, 0, 0], (10, 1))
    with pytest.raises(ValueError, match="truth row 0: norm 0 is not 1"):
        rf.rmse(q, np.zeros((10, 4)))
    use = np.ones(10)
    use[3] = np.nan
    with pytest.raises(ValueError, match="use: row 3 is NaN"):
        rf.rmse(q, q, use=use)
    assert rf.rmse(q, q, use=np.array([1, 0] * 5))["n_used"] == 5
