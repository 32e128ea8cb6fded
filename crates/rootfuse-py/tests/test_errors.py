"""Bad input: a TypeError/ValueError naming the argument and what was expected; bad samples
inside valid arrays are skipped and flagged. Never a crash."""

import numpy as np
import pytest

import rootfuse as rf

N = 50
GYR = np.zeros((N, 3))
ACC = np.tile([0.0, 0.0, 9.81], (N, 1))
MAG = np.tile([0.0, 20.0, -40.0], (N, 1))


@pytest.fixture
def f():
    return rf.Filter("sqrt-eskf")


def test_wrong_shape(f):
    with pytest.raises(ValueError, match=r"gyr: expected shape \(N, 3\), got \(50, 4\)"):
        f.update_batch(np.zeros((N, 4)), ACC, MAG, 0.01)
    with pytest.raises(ValueError, match=r"acc: expected shape \(N, 3\), got \(150,\)"):
        f.update_batch(GYR, ACC.ravel(), MAG, 0.01)


def test_wrong_dtype(f):
    with pytest.raises(TypeError, match="gyr: expected a float32 or float64 numpy array, got dtype int64"):
        f.update_batch(np.zeros((N, 3), dtype=np.int64), ACC, MAG, 0.01)
    with pytest.raises(TypeError, match="acc: expected a numpy array"):
        f.update_batch(GYR, ACC.tolist(), MAG, 0.01)


def test_lengths_disagree(f):
    with pytest.raises(ValueError, match="mag: has 49 samples but gyr has 50"):
        f.update_batch(GYR, ACC, MAG[:-1], 0.01)
    with pytest.raises(ValueError, match="dt: has 3 samples but gyr has 50"):
        f.update_batch(GYR, ACC, MAG, np.full(3, 0.01))
    with pytest.raises(ValueError, match="t: has 49 samples"):
        f.update_batch(GYR, ACC, MAG, t=np.arange(N - 1) * 0.01)


def test_sampling_arguments(f):
    with pytest.raises(ValueError, match="dt, t: missing"):
        f.update_batch(GYR, ACC, MAG)
    with pytest.raises(ValueError, match="not both"):
        f.update_batch(GYR, ACC, MAG, 0.01, t=np.arange(N) * 0.01)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="dt: expected a finite number > 0"):
            f.update_batch(GYR, ACC, MAG, bad)


def test_non_contiguous_is_copied(f):
    wide = np.zeros((N, 6))
    wide[:, 3:] = ACC
    g = rf.Filter("sqrt-eskf")
    a = f.update_batch(wide[:, :3], wide[:, 3:], MAG, 0.01)
    b = g.update_batch(GYR, ACC, MAG, 0.01)
    np.testing.assert_array_equal(a["quat"], b["quat"])
    fortran = np.asfortranarray(ACC)
    f.reset()
    c = f.update_batch(GYR, fortran, MAG, 0.01)
    np.testing.assert_array_equal(c["quat"], b["quat"])


def test_bad_samples_are_flagged_not_raised(f):
    gyr, acc, mag = GYR.copy(), ACC.copy(), MAG.copy()
    gyr[5] = np.nan
    acc[6] = [0.0, 0.0, 0.0]
    mag[7, 2] = -np.inf
    dt = np.full(N, 0.01)
    dt[8] = -0.01
    out = f.update_batch(gyr, acc, mag, dt)
    assert out["flags"][5] & rf.FLAG_GYR
    assert out["flags"][6] & rf.FLAG_ACC
    assert out["flags"][7] & rf.FLAG_MAG
    assert out["flags"][8] & rf.FLAG_DT
    assert np.isfinite(out["quat"]).all()
    np.testing.assert_array_equal(out["quat"][5], out["quat"][4])  # skipped sample: state kept
    r = f.rejections
    assert r["gyr"] == 1 and r["dt"] == 1 and r["acc"] == 1 and r["mag"] == 1


def test_nine_d_without_magnetometer_is_flagged(f):
    out = f.update_batch(GYR, ACC, None, 0.01)
    assert (out["flags"] & rf.FLAG_MAG).all()


def test_empty_arrays(f):
    out = f.update_batch(np.zeros((0, 3)), np.zeros((0, 3)), None, 0.01)
    assert out["quat"].shape == (0, 4) and out["flags"].shape == (0,)


def test_bad_filter_and_params():
    with pytest.raises(ValueError, match="name: unknown filter `nope`"):
        rf.Filter("nope")
    with pytest.raises(ValueError, match="^kp: "):
        rf.Filter("mahony", kp=-1.0)
    with pytest.raises(ValueError, match="^bogus: "):
        rf.Filter("mahony", bogus=1.0)
    with pytest.raises(TypeError, match="kp: expected a number, got a string"):
        rf.Filter("mahony", kp="0.5")
    with pytest.raises(ValueError, match="dof: expected 6 or 9, got 7"):
        rf.Filter("mahony", dof=7)
    # gyro has no 6D/9D choice: a dof for it is refused, not ignored.
    for dof in (6, 9):
        with pytest.raises(
            ValueError,
            match=r"^dof: filter `gyro` has no 6D/9D choice .*: complementary, mahony, ",
        ):
            rf.Filter("gyro", dof=dof)
    with pytest.raises(ValueError, match='precision: expected "f32" or "f64"'):
        rf.Filter("mahony", precision="f16")


def test_update_arguments(f):
    with pytest.raises(ValueError, match=r"gyr: expected 3 values"):
        f.update([0.0, 0.0], [0.0, 0.0, 9.81], dt=0.01)
    with pytest.raises(TypeError, match="acc: expected three numbers"):
        f.update([0.0, 0.0, 0.0], "abc", dt=0.01)
    assert f.update([np.nan, 0.0, 0.0], [0.0, 0.0, 9.81], dt=0.01) & rf.FLAG_GYR


def test_smooth_errors():
    with pytest.raises(ValueError, match="attitude covariance"):
        rf.smooth("mahony", GYR, ACC, MAG, dt=0.01)
    with pytest.raises(ValueError, match="dt: the smoother takes sample times"):
        rf.smooth("sqrt-eskf", GYR, ACC, MAG, dt=np.full(N, 0.01))


def test_many_errors():
    with pytest.raises(ValueError, match=r"gyr: expected shape \(C, N, 3\)"):
        rf.run_many("mahony", GYR, ACC, dt=0.01)
    with pytest.raises(ValueError, match=r"acc\[1\]: has 49 samples but gyr\[1\] has 50"):
        rf.run_many("mahony", [GYR, GYR], [ACC, ACC[:-1]], dt=0.01)
    with pytest.raises(ValueError, match="channel_params: has 1 entries but there are 2 channels"):
        rf.run_many("mahony", [GYR, GYR], [ACC, ACC], dt=0.01, channel_params=[{}])
    # The channel at fault is named.
    with pytest.raises(ValueError, match=r"channel_params\[1\]: .*kp"):
        rf.run_many("mahony", [GYR, GYR], [ACC, ACC], dt=0.01, channel_params=[{}, {"kp": -1.0}])
    with pytest.raises(TypeError, match=r"channel_params\[0\]: expected a dict of parameters, got float"):
        rf.run_many("mahony", [GYR, GYR], [ACC, ACC], dt=0.01, channel_params=[1.0, {}])
    with pytest.raises(ValueError, match=r"dt: expected shape \(C, N\)"):
        rf.run_many("mahony", GYR[None], ACC[None], dt=np.zeros((1, 2, 3)))


def test_lsq_errors():
    with pytest.raises(ValueError, match="form: unknown form"):
        rf.Rls("nope", 2)
    with pytest.raises(ValueError, match="n: expected a state size from 1 to 8, got 9"):
        rf.Rls("potter", 9)
    with pytest.raises(ValueError, match="Rls: forgetting factor"):
        rf.Rls("potter", 2, lam=1.5)
    with pytest.raises(ValueError, match="Rls: initial covariance not positive definite"):
        rf.Rls("potter", 2, p0=np.array([[1.0, 2.0], [2.0, 1.0]]))
    r = rf.Rls("bierman-ud", 2)
    with pytest.raises(ValueError, match=r"h: expected shape \(2,\), got \(3,\)"):
        r.update(np.ones(3), 1.0)
    with pytest.raises(ValueError, match=r"h: expected shape \(K, 2\)"):
        r.run(np.ones((4, 3)), np.ones(4))
    with pytest.raises(ValueError, match="z: has 3 entries but h has 4 rows"):
        r.run(np.ones((4, 2)), np.ones(3))
    assert not r.update(np.array([np.nan, 1.0]), 1.0)
    assert r.health["rejected_input"] == 1
    with pytest.raises(ValueError, match="lstsq: non-finite value in design matrix H at \\(1, 0\\)"):
        h = np.ones((3, 2)); h[1, 0] = np.nan
        rf.lstsq(h, np.ones(3))
    with pytest.raises(ValueError, match='method: expected "qr"'):
        rf.lstsq(np.ones((3, 2)), np.ones(3), method="lu")
    with pytest.raises(ValueError, match="rank"):
        rf.lstsq(np.ones((3, 2)), np.ones(3), method="qr")
    with pytest.raises(ValueError, match="scenario: unknown"):
        rf.stress("nope", scale=0.01)
    with pytest.raises(ValueError, match="scale: at most 100"):
        rf.stress("benign", scale=1e6)


def test_eval_errors(tmp_path):
    q = np.tile([1.0, 0.0, 0.0, 0.0], (5, 1))
    with pytest.raises(ValueError, match="truth: has 4 samples but est has 5"):
        rf.rmse(q, q[:4])
    with pytest.raises(ValueError, match="dof: expected 6 or 9"):
        rf.rmse(q, q, dof=7)
    with pytest.raises(ValueError, match="scenario: "):
        rf.simulate("nope")
    # FileNotFoundError, as estimate_table raises it (an OSError).
    with pytest.raises(FileNotFoundError, match="cannot read"):
        rf.read_csv(tmp_path / "missing.csv")
    with pytest.raises(FileNotFoundError, match="cannot read"):
        rf.read_estimates(tmp_path / "missing.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,x,0,0,0,9.8\n")
    with pytest.raises(ValueError, match="bad.csv: line 3"):
        rf.read_csv(bad)


def test_version():
    import importlib.metadata

    assert rf.__version__ == importlib.metadata.version("rootfuse")


def test_integer_arguments_are_named():
    """A dof or seed out of range is a ValueError naming the argument, not a bare
    OverflowError from the conversion."""
    for bad in (300, -1, 7, 2**70):
        with pytest.raises(ValueError, match=f"dof: expected 6 or 9, got {bad}"):
            rf.Filter("mahony", dof=bad)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (5, 1))
    with pytest.raises(ValueError, match="dof: expected 6 or 9, got 300"):
        rf.rmse(q, q, dof=300)
    for bad in (-1, 2**64):
        with pytest.raises(ValueError, match=f"seed: expected a whole number in \\[0, 2\\*\\*64\\), got {bad}"):
            rf.simulate("static", seed=bad)
