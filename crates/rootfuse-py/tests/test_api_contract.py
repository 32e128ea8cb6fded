"""Python given what a new user tries (issue #34, item 7): impossible sizes are a MemoryError
before anything is allocated, and values that would be silently wrong are refused or kept;
every refusal names the argument and says what was expected."""

import inspect
import threading

import numpy as np
import pytest

import rootfuse as rf

N = 20
GYR = np.zeros((N, 3))
ACC = np.tile([0.0, 0.0, 9.81], (N, 1))
MAG = np.tile([0.0, 20.0, -40.0], (N, 1))
Q = np.tile([1.0, 0.0, 0.0, 0.0], (N, 1))
H = np.stack([np.ones(8), np.arange(8.0)], axis=1)
Z = 2 + 3 * H[:, 1]


def test_impossible_channel_count_is_a_memory_error():
    # (2**40, 0, 3) holds no memory but claims 2**40 channels: allocated as asked, the
    # interpreter aborts on an 8.8 TB allocation.
    empty = np.empty((2**40, 0, 3))
    with pytest.raises(MemoryError, match="channels need about 1280 bytes each"):
        rf.run_many("mahony", empty, empty, None, 0.01, dof=6)


def test_bias_is_checked_in_the_filters_precision():
    f = rf.Filter("flagship", precision="f32")
    with pytest.raises(ValueError, match="not representable in this f32 filter"):
        f.set_bias([1e39, 0, 0])
    # Finite in f64, but no gyro bias is above 1 rad/s: refused there as a unit error.
    with pytest.raises(ValueError, match=r"`bias` = 1000+ is outside \[-1, 1\]; nothing was set"):
        rf.Filter("flagship").set_bias([1e39, 0, 0])
    assert rf.Filter("flagship").set_bias([0.5, 0, 0])


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


# (a) A bool is no number: float(True) is 1.0, so `kp=True` ran with kp = 1.


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: rf.Filter("mahony", kp=True), r"kp: expected a number, got a bool \(True\)"),
        (lambda: rf.Filter("mahony", kp=np.True_), r"kp: expected a number, got a bool"),
        (lambda: rf.Filter("mahony").update_batch(GYR, ACC, MAG, True), r"dt: expected a number .*got a bool"),
        (lambda: rf.Filter("mahony").update([0, 0, 0], [0, 0, 9.81], dt=True), r"argument 'dt': expected a number, got a bool"),
        (lambda: rf.Filter("mahony").set_heading(True), r"argument 'heading': expected a number"),
        (lambda: rf.Filter("mahony").set_bias([True, 0, 0]), r"bias\[0\]: expected a number, got a bool"),
        (lambda: rf.Filter("mahony", dof=True), r"argument 'dof': expected 6 or 9, got a bool"),
        (lambda: rf.Rls("potter", True), r"argument 'n': expected a whole number, got a bool"),
        (lambda: rf.Rls("potter", 2, lam=True), r"argument 'lam': expected a number, got a bool"),
        (lambda: rf.Rls("potter", 2, p0=True), r"p0: expected a number or an \(n, n\) matrix, got a bool"),
        (lambda: rf.Rls("potter", 2).update(np.ones(2), True), r"argument 'z': expected a number"),
        (lambda: rf.Rls("potter", 2).run(H, Z, True), r"weights: expected a number or a \(K,\) array, got a bool"),
        (lambda: rf.simulate("static", seed=True), r"argument 'seed': expected a whole number .*got a bool"),
        (lambda: rf.simulate("static", duration_s=True), r"argument 'duration_s': expected a number"),
        (lambda: rf.lstsq(H, Z, rank_tolerance=True), r"argument 'rank_tolerance': expected a number"),
        (lambda: rf.lstsq(H, Z, refinement_steps=True), r"argument 'refinement_steps': expected a whole number"),
        (lambda: rf.stress("benign", scale=True), r"argument 'scale': expected a number"),
        (lambda: rf.run_many("mahony", GYR[None], ACC[None], None, True, dof=6), r"dt: expected a number .*got a bool"),
        (lambda: rf.run_many("mahony", GYR[None], ACC[None], None, 0.01, dof=6, channel_params=[{"ki": False}]),
         r"ki: expected a number, got a bool"),
    ],
)
def test_booleans_are_not_numbers(call, match):
    with pytest.raises(TypeError, match=match):
        call()


def test_a_switch_parameter_takes_a_bool():
    # `coning` is 0 or 1: a bool is what it means.
    assert rf.Filter("complementary-reconstruction", coning=False).params["coning"] == 0.0
    assert rf.Filter("complementary-reconstruction", coning=np.True_).params["coning"] == 1.0


# (b) Parameter names are exact.


def test_parameter_names_are_exact():
    for bad in (" kp ", "kp ", "Kp", "kp=1,ki"):
        with pytest.raises(ValueError, match=r"unknown parameter .* of mahony.*\(valid: kp, ki, "):
            rf.Filter("mahony", **{bad: 1.0})
    with pytest.raises(ValueError, match=r"names are exact: no spaces"):
        rf.Filter("mahony", **{" kp ": 1.0})
    with pytest.raises(ValueError, match=r"unknown parameter \" kp \""):
        rf.run_many("mahony", GYR[None], ACC[None], None, 0.01, dof=6, channel_params=[{" kp ": 1.0}])
    assert rf.Filter("mahony", kp=1.0).params["kp"] == 1.0


# (c) rank_tolerance


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_rank_tolerance_must_be_finite_and_not_negative(bad):
    with pytest.raises(ValueError, match="rank_tolerance: expected a finite number ≥ 0"):
        rf.lstsq(H, Z, method="svd", rank_tolerance=bad)
    np.testing.assert_allclose(rf.lstsq(H, Z, method="svd", rank_tolerance=0.0)["estimate"], [2, 3])


# (d) Asymmetric covariances are refused, not read by one triangle.


def test_asymmetric_covariance_and_prior_are_refused():
    r = np.eye(len(Z))
    r[0, 1] = 0.5
    with pytest.raises(ValueError, match=r"covariance: not symmetric: \[0, 1\] = 0.5 but \[1, 0\] = 0"):
        rf.lstsq(H, Z, covariance=r)
    r[1, 0] = 0.5 * (1 + 1e-12)  # rounding, within 1e-9 of the largest entry
    np.testing.assert_allclose(rf.lstsq(H, Z, covariance=r)["estimate"], [2, 3], rtol=1e-9)
    p0 = np.array([[1e4, 3e3], [1e3, 1e4]])
    with pytest.raises(ValueError, match=r"p0: not symmetric: \[0, 1\] = 3000 but \[1, 0\] = 1000 \(difference 2.000e3, 2.0e-1 of the largest"):
        rf.Rls("conventional", 2, p0=p0)
    p0[0, 1] = 1e3
    np.testing.assert_allclose(rf.Rls("conventional", 2, p0=p0).covariance, p0, rtol=1e-12)


# (e) The writers refuse what the readers refuse, with the reader's line and column.


def test_write_recording_refuses_what_read_csv_refuses(tmp_path):
    t = np.arange(N) * 0.01
    gyr = GYR.copy()
    gyr[3, 1] = np.nan
    path = tmp_path / "rec.csv"
    with pytest.raises(ValueError, match=r"row 3 \(line 5\), column `gy`: gyroscope value NaN is not finite"):
        rf.write_recording(path, t, gyr, ACC)
    assert not path.exists()
    # The reader names the same line and column for the same data.
    rows = "\n".join(",".join(str(v) for v in [t[i], *gyr[i], *ACC[i]]) for i in range(N))
    path.write_text("t,gx,gy,gz,ax,ay,az\n" + rows + "\n")
    with pytest.raises(ValueError, match=r"line 5, column `gy`"):
        rf.read_csv(path)
    path.unlink()
    t_bad = t.copy()
    t_bad[2] = t_bad[1]
    with pytest.raises(ValueError, match=r"row 2 \(line 4\), column `t`: time 0.01 does not increase"):
        rf.write_recording(path, t_bad, GYR, ACC)
    assert not path.exists()
    # What is written reads back as it was.
    rf.write_recording(path, t, GYR, ACC, MAG)
    back = rf.read_csv(path)
    for k, v in (("t", t), ("gyr", GYR), ("acc", ACC), ("mag", MAG)):
        np.testing.assert_array_equal(back[k], v)


def test_write_estimates_refuses_what_read_estimates_refuses_and_every_column_reads_back(tmp_path):
    t = np.arange(N) * 0.01
    path = tmp_path / "est.csv"
    t_bad = t.copy()
    t_bad[5] = np.nan
    with pytest.raises(ValueError, match=r"row 5 \(line 7\), column `t`: time NaN is not finite"):
        rf.write_estimates(path, t_bad, Q)
    q_bad = Q.copy()
    q_bad[4, 0] = np.nan
    with pytest.raises(ValueError, match=r"row 4 \(line 6\), column `qw`"):
        rf.write_estimates(path, t, q_bad)
    assert not path.exists()
    # `bx`, `p_xx`, `flags`: every column is kept, NaN in them too.
    bx = np.linspace(0, 1e-3, N)
    p_xx = np.full(N, 1e-4)
    p_xx[2] = np.nan
    flags = (np.arange(N) % 3).astype(float)
    rf.write_estimates(path, t, Q, {"bx": bx, "p_xx": p_xx, "flags": flags})
    back = rf.read_estimates(path)
    assert set(back) == {"t", "quat", "bx", "p_xx", "flags"}
    np.testing.assert_array_equal(back["t"], t)
    np.testing.assert_array_equal(back["quat"], Q)
    np.testing.assert_array_equal(back["bx"], bx)
    np.testing.assert_array_equal(back["p_xx"], p_xx)
    np.testing.assert_array_equal(back["flags"], flags)
    # The uint8 flags update_batch returns are written as they are (and bool columns too).
    rf.write_estimates(path, t, Q, {"flags": flags.astype(np.uint8), "rest": np.arange(N) % 2 == 0})
    back = rf.read_estimates(path)
    np.testing.assert_array_equal(back["flags"], flags)
    np.testing.assert_array_equal(back["rest"], (np.arange(N) % 2 == 0).astype(float))


# (f) Messages that name the right argument; defaults that help() can show.


def test_use_messages_name_use():
    with pytest.raises(ValueError, match=r"use: has 3 samples but est has 20") as e:
        rf.rmse(Q, Q, use=np.ones(3, dtype=bool))
    assert "gyr" not in str(e.value)
    with pytest.raises(ValueError, match=r"use: expected a 1-D array or list of N booleans .*got shape \(20, 1\)") as e:
        rf.rmse(Q, Q, use=np.ones((N, 1), dtype=bool))
    assert "float" not in str(e.value)
    with pytest.raises(TypeError, match=r"use: expected a 1-D array or list of N booleans .*got int") as e:
        rf.rmse(Q, Q, use=1)
    assert "float" not in str(e.value)
    with pytest.raises(ValueError, match=r"use: has 3 samples but gyr has 20"):
        rf.write_recording("unused.csv", np.arange(N) * 0.01, GYR, ACC, use=[True] * 3)


def test_dt_of_the_wrong_type_says_what_dt_may_be():
    with pytest.raises(TypeError, match=r"dt: expected a number \(the step, s\) or a 1-D float array of per-sample steps \(s\), got str"):
        rf.Filter("mahony").update_batch(GYR, ACC, MAG, "0.01")


def test_device_params_that_are_no_table_are_rootfuses_error():
    pa = pytest.importorskip("pyarrow")
    import rootfuse.arrow as ra

    table = pa.table({"t": np.arange(N) * 0.01, "gx": GYR[:, 0], "gy": GYR[:, 1], "gz": GYR[:, 2],
                      "ax": ACC[:, 0], "ay": ACC[:, 1], "az": ACC[:, 2]})
    with pytest.raises(TypeError, match=r"device_params: expected \{device: \{name: value\}\} or a table") as e:
        ra.estimate_table(table, "mahony", dof=6, device_params=[1, 2])
    assert not isinstance(e.value, pa.ArrowException)
    with pytest.raises(TypeError, match=r"device_params: expected a dict"):
        ra.estimate_arrow(table, "mahony", dof=6, device_params=[1, 2])
    # A bad row is pyarrow's ArrowInvalid, a ValueError, as estimate_stream's doc says.
    bad = table.set_column(0, "t", pa.array(np.r_[0.0, 0.01, 0.01, np.arange(3, N) * 0.01]))
    with pytest.raises(ValueError, match=r"row 2, column `t`") as e:
        ra.estimate_stream(bad, "mahony", dof=6).read_all()
    assert isinstance(e.value, pa.ArrowInvalid)
    assert "ArrowInvalid" in ra.estimate_stream.__doc__ and "OSError" not in ra.estimate_stream.__doc__


def test_a_filter_busy_in_another_thread_says_so():
    n = 400_000
    gyr, acc, mag = np.zeros((n, 3)), np.tile([0.0, 0.0, 9.81], (n, 1)), np.tile([0.0, 20.0, -40.0], (n, 1))
    f = rf.Filter("flagship")
    worker = threading.Thread(target=lambda: f.update_batch(gyr, acc, mag, 0.01))
    worker.start()
    seen = None
    while worker.is_alive() and seen is None:
        try:
            f.quat  # noqa: B018 (a read while the other thread runs the filter)
        except RuntimeError as e:
            seen = str(e)
    worker.join()
    assert seen is not None, "update_batch finished before the filter could be seen busy"
    assert "a Filter is used by one thread at a time" in seen and "one Filter per thread" in seen
    f.update([0, 0, 0], [0, 0, 9.81], [0, 20, -40], dt=0.01)  # free again


def test_help_shows_real_defaults():
    for fn, defaults in (
        (rf.rmse, {"use": None, "dof": 9}),
        (rf.error_series, {"use": None, "dof": 9}),
        (rf.heading_offset, {"use": None}),
        (rf.consistency, {"use": None, "dof": 9, "floor_deg": 0.0, "skip": 0.1}),
        (rf.simulate, {"seed": 0, "duration_s": 10.0, "rate_hz": 100.0}),
        (rf.write_recording, {"use": None, "truth": None}),
    ):
        params = inspect.signature(fn).parameters
        for name, value in defaults.items():
            assert params[name].default == value, (fn.__name__, name, params[name].default)
    assert "Filter(name, *, dof=None" in rf.Filter.__doc__
    assert inspect.signature(rf.Filter).parameters["dof"].kind is inspect.Parameter.KEYWORD_ONLY


def test_set_bias_works_where_update_batch_reports_a_bias():
    b = [0.01, -0.02, 0.005]
    rest = lambda n, w=0.0: (np.full((n, 3), w), np.tile([0.0, 0.0, 9.81], (n, 1)), None, 0.01)  # noqa: E731
    # lsq-fusion: its drift estimate, from the first sample on (kept until a measurement).
    f = rf.Filter("lsq-fusion")
    assert f.set_bias(b)
    np.testing.assert_array_equal(f.bias, b)
    np.testing.assert_array_equal(f.update_batch(*rest(50))["bias"][-1], b)
    # complementary-reconstruction: in place of its still-period mean once the still period
    # (1 s) is over; during it the mean is being taken and a bias is not set.
    f = rf.Filter("complementary-reconstruction")
    assert not f.set_bias(b)
    np.testing.assert_allclose(f.update_batch(*rest(150, 0.003))["bias"][-1], 0.003)
    assert f.set_bias(b)
    np.testing.assert_array_equal(f.bias, b)
    np.testing.assert_array_equal(f.update_batch(*rest(50))["bias"], np.tile(b, (50, 1)))
    # heading-pipeline estimates one component (the heading rate about up): no 3-axis bias.
    f = rf.Filter("heading-pipeline")
    assert np.any(f.update_batch(GYR + 0.01, ACC, MAG, 0.01)["bias"] != 0)
    assert not f.set_bias(b)
    # Every other filter whose update_batch reports a bias takes one.
    for info in rf.filters():
        f = rf.Filter(info["name"])
        n = 150
        reports = np.any(f.update_batch(np.full((n, 3), 0.01), np.tile(ACC[0], (n, 1)), np.tile(MAG[0], (n, 1)), 0.01)["bias"] != 0)
        if reports and info["name"] != "heading-pipeline":
            assert f.set_bias(b), info["name"]
            np.testing.assert_allclose(f.bias, b, rtol=1e-12, err_msg=info["name"])


# (h) update_batch without the covariance; run_many's f32 default in its docstring.


def test_update_batch_can_leave_the_covariance_out():
    f = rf.Filter("flagship")
    with_cov = f.update_batch(GYR, ACC, MAG, 0.01)
    assert with_cov["covariance"].shape == (N, 3, 3)
    f.reset()
    without = f.update_batch(GYR, ACC, MAG, 0.01, covariance=False)
    assert set(without) == {"quat", "bias", "flags"}
    np.testing.assert_array_equal(without["quat"], with_cov["quat"])


def test_run_many_says_its_default_precision():
    assert inspect.signature(rf.run_many).parameters["precision"].default == "f32"
    assert '"f32"' in rf.run_many.__doc__ and "by default" in rf.run_many.__doc__


def test_flagship_state_is_set_with_its_uncertainty():
    # set_quat(q, sigma) and set_bias(b, sigma) reach the flagship's covariance; other
    # filters refuse sigma by name; a bad sigma changes nothing.
    rec = rf.simulate("slow-rotation", seed=2, duration_s=5.0)
    for precision, tol in (("f64", 1e-15), ("f32", 1e-9)):
        f = rf.Filter("flagship", precision=precision)
        f.update_batch(rec["gyr"], rec["acc"], rec["mag"], t=rec["t"])
        q = [np.cos(0.2), 0.0, 0.0, np.sin(0.2)]
        f.set_quat(q, sigma=0.01)
        assert np.allclose(f.covariance, np.eye(3) * 1e-4, atol=tol, rtol=1e-5)
        assert np.allclose(f.quat, q, atol=1e-6)
        before = f.covariance.copy()
        assert f.set_bias([0.01, 0.0, -0.02], sigma=1e-3) is True
        assert np.allclose(f.bias, [0.01, 0.0, -0.02], atol=1e-7)
        assert np.allclose(f.covariance, before, atol=tol, rtol=1e-5)
        for bad in (float("nan"), -1.0, True):
            with pytest.raises((ValueError, TypeError), match="sigma"):
                f.set_quat(q, sigma=bad)
        assert np.allclose(f.covariance, before, atol=tol, rtol=1e-5)
    with pytest.raises(ValueError, match="sigma: `mahony` carries no attitude covariance"):
        rf.Filter("mahony").set_quat([1.0, 0.0, 0.0, 0.0], sigma=0.1)
    with pytest.raises(ValueError, match="sigma: `gyro` carries no gyro-bias estimate"):
        rf.Filter("gyro").set_bias([0.0, 0.0, 0.0], sigma=0.1)
    # The EKF carries a covariance too: sigma is read back as sigma².
    ekf = rf.Filter("ekf")
    ekf.set_quat([1.0, 0.0, 0.0, 0.0], sigma=0.05)
    assert np.allclose(ekf.covariance, np.eye(3) * 0.05**2, atol=1e-12)
    # A bias above 1 rad/s is a unit error, refused with nothing changed.
    with pytest.raises(ValueError, match="bias"):
        ekf.set_bias([0.0, 2.0, 0.0])
    assert np.allclose(ekf.bias, 0.0)


def test_gyro_scale_follows_the_readings_scale():
    # The flagship's online estimate of the gyroscope's scale error (a fraction per axis):
    # readings 0.5 % larger raise it by 0.5 % on every axis (to 0.1 %; the simulated IMU has
    # its own, which both runs share), 6D and 9D; zeros before its first window closes and
    # for the filters without one.
    r = rf.simulate("fast-rotation", seed=0, duration_s=180.0)
    for dof in (9, 6):
        scales = []
        for factor in (1.0, 1.005):
            f = rf.Filter("flagship", dof=dof)
            np.testing.assert_array_equal(f.gyro_scale, np.zeros(3))
            f.update_batch(r["gyr"] * factor, r["acc"], r["mag"] if dof == 9 else None, t=r["t"])
            scales.append(f.gyro_scale)
        np.testing.assert_allclose(scales[1] - scales[0], 0.005, atol=0.001, err_msg=f"{dof}D")
    f = rf.Filter("mahony")
    f.update_batch(r["gyr"], r["acc"], None, t=r["t"])
    np.testing.assert_array_equal(f.gyro_scale, np.zeros(3))


def test_smooth_shares_the_online_scale_estimate():
    # By default (smoothing_gyro_scale=1) the smoother first runs the flagship online in
    # float32 at half the rate (each pair of samples one: the mean angular rate, the second
    # accelerometer reading), and reports (and divides both passes' readings by) the scale
    # error that run ends with; 0 skips that run.
    r = rf.simulate("fast-rotation", seed=1, duration_s=60.0)
    plain = rf.smooth("flagship", r["gyr"], r["acc"], None, t=r["t"], dof=6, smoothing_gyro_scale=0)
    assert "gyro_scale" not in plain
    shared = rf.smooth("flagship", r["gyr"], r["acc"], None, t=r["t"], dof=6)
    n = len(r["t"]) // 2 * 2
    pairs = lambda x: x[:n].reshape(n // 2, 2, 3).mean(axis=1)  # noqa: E731
    f = rf.Filter("flagship", dof=6, precision="f32")
    f.update_batch(pairs(r["gyr"]), r["acc"][1:n:2], None, t=r["t"][1:n:2])
    np.testing.assert_array_equal(shared["gyro_scale"], f.gyro_scale)
    # At the full rate the estimate is the same to within its noise.
    full = rf.Filter("flagship", dof=6, precision="f32")
    full.update_batch(r["gyr"], r["acc"], None, t=r["t"])
    np.testing.assert_allclose(shared["gyro_scale"], full.gyro_scale, atol=2e-4)
    assert np.any(f.gyro_scale != 0)
    assert not np.array_equal(shared["quat"], plain["quat"])


def test_run_many_reports_each_channels_gyro_scale():
    # A fleet's per-device calibration: run_many's final state carries each channel's scale
    # estimate, bit for bit that of a Filter of the same precision on that channel, and the
    # channel's own (readings 0.3 % and 0.6 % larger here).
    r = rf.simulate("fast-rotation", seed=2, duration_s=120.0)
    factors = (1.0, 1.003, 1.006)
    gyr = np.stack([r["gyr"] * f for f in factors])
    acc = np.stack([r["acc"]] * 3)
    t = np.stack([r["t"]] * 3)
    final = rf.run_many("flagship", gyr, acc, None, t=t, dof=6, series=False)
    assert final["gyro_scale"].shape == (3, 3)
    for c in range(3):
        f = rf.Filter("flagship", dof=6, precision="f32")
        f.update_batch(gyr[c], acc[c], None, t=r["t"])
        np.testing.assert_array_equal(final["gyro_scale"][c], f.gyro_scale)
    # In 6D the axes are held to their mean, and the mean follows the readings (measured
    # 0.0063 for 0.006).
    assert abs(np.mean(final["gyro_scale"][2] - final["gyro_scale"][0]) - 0.006) < 0.001, final["gyro_scale"]
    mahony = rf.run_many("mahony", gyr, acc, None, t=t, dof=6, series=False)
    np.testing.assert_array_equal(mahony["gyro_scale"], np.zeros((3, 3)))
