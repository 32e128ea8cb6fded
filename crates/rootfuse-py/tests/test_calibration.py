"""The batch calibration fit from NumPy, against a known truth (closed-form data)."""

import numpy as np
import pytest

import rootfuse as rf


def _directions(n, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_full_rotation_recovers_hard_and_soft_iron():
    # Truth: raw = S⁻¹·m + h with |m| = 50, S symmetric positive definite.
    s_true = np.array([[1.04, 0.02, -0.01], [0.02, 0.97, 0.03], [-0.01, 0.03, 1.01]])
    h_true = np.array([15.0, -8.0, 4.0])
    m = 50.0 * _directions(2000, 1)
    raw = m @ np.linalg.inv(s_true).T + h_true
    raw += np.random.default_rng(2).normal(scale=0.1, size=raw.shape)
    fit = rf.fit_ellipsoid_calibration(raw, norm=50.0)
    assert fit["model"] == "full"
    assert np.linalg.norm(fit["offset"] - h_true) < 0.005 * 50.0
    assert np.linalg.norm(fit["matrix"] - s_true) / np.linalg.norm(s_true) < 0.01
    cal = (raw - fit["offset"]) @ fit["matrix"].T
    norms = np.linalg.norm(cal, axis=1)
    assert np.std(norms) / 50.0 < 0.01
    assert fit["coverage"] > 0.9


def test_one_axis_turn_says_what_it_could_not_determine():
    angle = np.linspace(0.0, 4.0 * np.pi, 800)
    m = 50.0 * np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=1)
    # Sensor noise: an exactly constant axis would be refused as saturated.
    raw = m + np.array([12.0, -7.0, 3.0])
    raw += np.random.default_rng(3).normal(scale=0.1, size=raw.shape)
    fit = rf.fit_ellipsoid_calibration(raw)
    assert fit["model"] != "full"
    assert [name for name, _ in fit["refused"]][:1] == ["full"]
    np.testing.assert_allclose(fit["offset"][:2], [12.0, -7.0], atol=0.05)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="samples: expected shape"):
        rf.fit_ellipsoid_calibration(np.zeros((20, 2)))
    with pytest.raises(ValueError, match="fit_ellipsoid_calibration"):
        rf.fit_ellipsoid_calibration(np.ones((5, 3)))
    with pytest.raises(ValueError, match="fit_ellipsoid_calibration"):
        rf.fit_ellipsoid_calibration(np.tile([10.0, 20.0, 30.0], (100, 1)))


def test_a_cap_of_directions_is_refused_unless_allowed():
    # Directions within ~35° of one axis: the condition test passes, the fit extrapolates.
    d = _directions(4000, 4)
    cap = d[d[:, 2] > 0.82]
    raw = 50.0 * cap + np.array([12.0, -7.0, 3.0])
    raw += np.random.default_rng(5).normal(scale=0.5, size=raw.shape)
    with pytest.raises(ValueError, match=r"cover \d+ % of the sphere of directions, at least 40 % needed"):
        rf.fit_ellipsoid_calibration(raw)
    fit = rf.fit_ellipsoid_calibration(raw, min_coverage=0.0)
    assert fit["coverage"] < 0.5
