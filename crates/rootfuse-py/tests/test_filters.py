"""Filters from Python equal the Rust library bit for bit (compared with `rootfuse run`
output, which writes shortest round-trip numbers), and the state API works."""

import csv
import re
import subprocess

import numpy as np
import pytest

import rootfuse as rf

NAMES = [f["name"] for f in rf.filters()]


def read_cli_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    cols = {h: np.array([float(r[i]) for r in body]) for i, h in enumerate(header)}
    return cols


def sim_with_bad_samples(tmp_path, dof=9):
    rec = rf.simulate("fast-rotation", seed=3, duration_s=4.0, rate_hz=100.0)
    gyr, acc = rec["gyr"].copy(), rec["acc"].copy()
    mag = rec["mag"].copy() if rec["mag"] is not None else None
    # The CSV reader refuses non-finite values, so the bad samples here are finite ones the
    # filters skip (NaN/inf are covered in test_errors.py).
    gyr[10, 1] = 1e6          # saturated gyroscope, whole sample skipped: flag 2
    acc[20, :] = 0.0          # accelerometer correction skipped: flag 4
    if mag is not None:
        mag[30, :] = 0.0      # magnetometer correction skipped: flag 8
    path = tmp_path / "sim.csv"
    rf.write_recording(path, rec["t"], gyr, acc, mag, truth=rec["truth"], use=rec["use"])
    return path


def run_cli(cli, path, out, name, precision, dof, extra=()):
    cmd = [cli, "run", str(path), "--filter", name, "--precision", precision, "--out", str(out)]
    if dof is not None:
        cmd += ["--dof", str(dof)]
    cmd += list(extra)
    subprocess.run(cmd, check=True, capture_output=True)
    return read_cli_csv(out / f"{path.stem}.csv")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_update_batch_equals_rust_bit_for_bit(cli, tmp_path, name, precision):
    path = sim_with_bad_samples(tmp_path)
    dof = None if name == "gyro" else 9
    f = rf.Filter(name, dof=dof, precision=precision)
    has_cov = f.covariance is not None
    extra = ["--bias", "--flags"] + (["--covariance"] if has_cov else [])
    ref = run_cli(cli, path, tmp_path / "out", name, precision, dof, extra)
    rec = rf.read_csv(path)
    out = f.update_batch(rec["gyr"], rec["acc"], rec["mag"], t=rec["t"])
    for k, col in enumerate(["qw", "qx", "qy", "qz"]):
        np.testing.assert_array_equal(out["quat"][:, k], ref[col], err_msg=f"{name} {precision} {col}")
    for k, col in enumerate(["bx", "by", "bz"]):
        np.testing.assert_array_equal(out["bias"][:, k], ref[col])
    np.testing.assert_array_equal(out["flags"], ref["flags"].astype(np.uint8))
    assert out["flags"][10] & rf.FLAG_GYR
    assert out["flags"][20] & rf.FLAG_ACC
    if has_cov:
        p = out["covariance"]
        for col, (r, c) in zip(["p_xx", "p_xy", "p_xz", "p_yy", "p_yz", "p_zz"],
                               [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]):
            np.testing.assert_array_equal(p[:, r, c], ref[col])
    else:
        assert "covariance" not in out


@pytest.mark.parametrize("precision", ["f32", "f64"])
@pytest.mark.parametrize("dof", [6, 9])
def test_flagship_on_broad_equals_rust(cli, broad_dir, tmp_path, precision, dof):
    path = sorted(broad_dir.glob("02_*.csv"))[0]
    ref = run_cli(cli, path, tmp_path, "flagship", precision, dof, ["--flags"])
    rec = rf.read_csv(path)
    out = rf.Filter("flagship", dof=dof, precision=precision).update_batch(rec["gyr"], rec["acc"], rec["mag"], t=rec["t"])
    np.testing.assert_array_equal(out["quat"], np.stack([ref[c] for c in ["qw", "qx", "qy", "qz"]], axis=1))
    np.testing.assert_array_equal(out["flags"], ref["flags"].astype(np.uint8))


def test_smooth_equals_rust_offline(cli, tmp_path):
    path = sim_with_bad_samples(tmp_path)
    ref = run_cli(cli, path, tmp_path / "out", "sqrt-eskf", "f64", 9, ["--offline"])
    rec = rf.read_csv(path)
    out = rf.smooth("sqrt-eskf", rec["gyr"], rec["acc"], rec["mag"], t=rec["t"], dof=9)
    np.testing.assert_array_equal(out["quat"], np.stack([ref[c] for c in ["qw", "qx", "qy", "qz"]], axis=1))
    assert out["forward_only"] >= 0


def test_smooth_names_arrays_in_other_units():
    # A gyroscope in deg/s given as arrays: smooth says so (it ran quietly, far off).
    rec = rf.simulate("slow-rotation", seed=3, duration_s=60.0)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rf.smooth("flagship", rec["gyr"], rec["acc"], rec["mag"], t=rec["t"])
    with pytest.warns(UserWarning, match=r"smooth: gyroscope: .*look like deg/s.*convert this sensor's \(gyro=deg/s\)"):
        rf.smooth("flagship", np.rad2deg(rec["gyr"]), rec["acc"], rec["mag"], t=rec["t"])


def test_filter_streams_name_arrays_in_other_units():
    """update_batch and update check a stream's first samples as smooth checks its arrays: a
    gyroscope in deg/s, an accelerometer in g or a field in nT ran quietly (the field in nT
    was refused at every sample by max_mag). One warning per sensor and stream, fed in
    chunks or whole; none for arrays in the filters' units; reset() starts a new stream."""
    import warnings

    rec = rf.simulate("slow-rotation", seed=3, duration_s=60.0)
    g, a, m, t = rec["gyr"], rec["acc"], rec["mag"], rec["t"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rf.Filter("flagship").update_batch(g, a, m, t=t)
        f = rf.Filter("mahony")
        for i in range(600):
            f.update(g[i], a[i], m[i], dt=t[1] - t[0])
    f = rf.Filter("flagship")
    with pytest.warns(UserWarning) as seen:
        for chunk in np.array_split(np.arange(len(t)), 6):
            f.update_batch(np.rad2deg(g[chunk]), a[chunk], m[chunk], t=t[chunk])
    messages = [str(w.message) for w in seen]
    assert len(messages) == 1, messages
    assert re.search(r"update_batch: gyroscope: .*look like deg/s.*convert this sensor's \(gyro=deg/s\)", messages[0])
    f.reset()
    with pytest.warns(UserWarning, match=r"update_batch: magnetometer: .*look like nT"):
        f.update_batch(g, a, m * 1000, t=t)
    assert f.rejections["mag"] == len(t)
    f = rf.Filter("mahony")
    with pytest.warns(UserWarning) as seen:
        for i in range(600):
            f.update(g[i], a[i] / 9.80665, m[i], dt=t[1] - t[0])
    messages = [str(w.message) for w in seen]
    assert len(messages) == 1 and re.search(r"update: accelerometer: .*look like g", messages[0]), messages
    # A 6D filter never reads the field, and a max_mag set for nT takes it: nothing to say
    # about its unit. A first chunk without a usable reading is no dead sensor; a slow rate
    # (2 Hz, within max_dt) is no time in ms.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rf.Filter("flagship", dof=6).update_batch(g, a, m * 1000, t=t)
        f = rf.Filter("flagship", max_mag=1e6)
        f.update_batch(g, a, m * 1000, t=t)
        assert f.rejections["mag"] == 0
        f = rf.Filter("flagship")
        nan = np.full((100, 3), np.nan)
        f.update_batch(nan, nan, nan, t=t[:100])
        f.update_batch(g[100:], a[100:], m[100:], t=t[100:])
        rf.Filter("mahony").update_batch(g[::50], a[::50], m[::50], t=t[::50])


def test_unit_warnings_raised_as_errors_leave_the_stream_as_it_was():
    """A unit warning turned into an error leaves the filter and its check as they were: the
    same call raises it again (a call long enough to end the check: 12 000 samples), and the
    warnings of a call are delivered in turn (one raised as an error stops the rest, and
    those delivered are not repeated)."""
    import warnings

    rec = rf.simulate("slow-rotation", seed=3, duration_s=120.0)
    g, a, m, t = np.rad2deg(rec["gyr"]), rec["acc"], rec["mag"] * 1000, rec["t"]
    f = rf.Filter("flagship")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _ in range(2):
            with pytest.raises(UserWarning, match="magnetometer"):
                f.update_batch(g, a, m, t=t)
            assert f.rejections["mag"] == 0
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        warnings.filterwarnings("error", message="update_batch: gyroscope")
        with pytest.raises(UserWarning, match="update_batch: gyroscope"):
            f.update_batch(g, a, m, t=t)
    assert [str(w.message).split(":")[1] for w in seen] == [" magnetometer"]
    with pytest.warns(UserWarning) as seen:
        f.update_batch(g, a, m, t=t)
    assert [str(w.message).split(":")[1] for w in seen] == [" gyroscope"]
    assert f.rejections["mag"] > len(t) / 2  # the filter ran once: a field in nT is refused
    f = rf.Filter("mahony")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserWarning, match="update: magnetometer"):
            for i in range(600):
                f.update(rec["gyr"][i], a[i], m[i], dt=t[1] - t[0])
        with pytest.raises(UserWarning, match="update: magnetometer"):
            f.update(rec["gyr"][i], a[i], m[i], dt=t[1] - t[0])
    # update() has no call of many steps to judge: its first 256 say it.
    f = rf.Filter("mahony")
    with pytest.warns(UserWarning, match=r"update: 256 of 256 samples will be skipped .*divide ms by 1000"):
        for i in range(300):
            f.update(rec["gyr"][i], rec["acc"][i], rec["mag"][i], dt=10.0)


def test_run_many_names_channels_in_other_units():
    """run_many checks the first, the last and two channels between: a fleet whose last
    channel is in g is named with that channel's index."""
    import warnings

    recs = [rf.simulate("slow-rotation", seed=s, duration_s=20.0) for s in range(5)]
    g = np.stack([r["gyr"] for r in recs])
    a = np.stack([r["acc"] for r in recs])
    t = np.stack([r["t"] for r in recs])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rf.run_many("mahony", g, a, t=t, dof=6, series=False)
    a[-1] /= 9.80665
    with pytest.warns(UserWarning, match=r"run_many: channel 4: accelerometer: .*look like g"):
        rf.run_many("mahony", g, a, t=t, dof=6, series=False)
    # Each channel is judged by its own filter: a 6D first channel does not hide a 9D
    # channel's field in nT; steps in ms are named as update_batch names them.
    a[-1] *= 9.80665
    m = np.stack([r["mag"] for r in recs]) * 1000
    params = [{"dof": 6}] + [{}] * 4
    with pytest.warns(UserWarning, match=r"run_many: channel 1: magnetometer: .*look like nT"):
        rf.run_many("mahony", g, a, m, t=t, channel_params=params, series=False)
    with pytest.warns(UserWarning, match=r"run_many: channel 0: .*skipped for their time step.*divide ms by 1000"):
        rf.run_many("mahony", g, a, t=t * 1000, dof=6, series=False)
    # A channel is whole: a dead sensor is named however short it is.
    a[0] = 0.0
    with pytest.warns(UserWarning, match=r"run_many: channel 0: accelerometer: every reading checked \(2000\) is zero"):
        rf.run_many("mahony", g, a, t=t, dof=6, series=False)


def test_parameters_reach_the_filter(cli, tmp_path):
    path = sim_with_bad_samples(tmp_path)
    ref = run_cli(cli, path, tmp_path / "out", "mahony", "f64", 6, ["--param", "kp=0.8"])
    rec = rf.read_csv(path)
    f = rf.Filter("mahony", dof=6, kp=0.8)
    assert f.params["kp"] == 0.8 and f.dof == 6
    out = f.update_batch(rec["gyr"], rec["acc"], None, t=rec["t"])
    np.testing.assert_array_equal(out["quat"][:, 0], ref["qw"])
    default = rf.Filter("mahony", dof=6).update_batch(rec["gyr"], rec["acc"], None, t=rec["t"])
    assert not np.array_equal(default["quat"], out["quat"])


def test_update_one_sample_equals_batch():
    rec = rf.simulate("slow-rotation", seed=1, duration_s=2.0)
    a = rf.Filter("sqrt-eskf", precision="f32")
    b = rf.Filter("sqrt-eskf", precision="f32")
    batch = a.update_batch(rec["gyr"], rec["acc"], rec["mag"], 0.01)
    for i in range(len(rec["t"])):
        flags = b.update(rec["gyr"][i], rec["acc"][i], rec["mag"][i], dt=0.01)
        assert flags == batch["flags"][i]
    np.testing.assert_array_equal(b.quat, batch["quat"][-1])
    np.testing.assert_array_equal(b.bias, batch["bias"][-1])
    np.testing.assert_array_equal(b.covariance, batch["covariance"][-1])
    assert b.quat.shape == (4,) and b.bias.shape == (3,) and b.covariance.shape == (3, 3)
    assert set(b.rejections) == {"dt", "gyr", "acc", "mag", "gated", "mag_disturbed"}
    # update accepts plain sequences too
    b.update([0.0, 0.0, 0.0], [0.0, 0.0, 9.81], None, dt=0.01)


def test_reset_rebuilds_from_spec():
    rec = rf.simulate("slow-rotation", seed=2, duration_s=1.0)
    f = rf.Filter("madgwick", precision="f64", beta=0.1)
    first = f.update_batch(rec["gyr"], rec["acc"], rec["mag"], 0.01)["quat"]
    second = f.update_batch(rec["gyr"], rec["acc"], rec["mag"], 0.01)["quat"]
    assert not np.array_equal(first, second)  # continues from the state
    f.reset()
    again = f.update_batch(rec["gyr"], rec["acc"], rec["mag"], 0.01)["quat"]
    np.testing.assert_array_equal(first, again)
    assert f.params["beta"] == 0.1


def test_dt_forms_agree():
    rec = rf.simulate("slow-rotation", seed=4, duration_s=1.0, rate_hz=100.0)
    n = len(rec["t"])
    f = rf.Filter("mahony")
    a = f.update_batch(rec["gyr"], rec["acc"], rec["mag"], 0.01)
    f.reset()
    b = f.update_batch(rec["gyr"], rec["acc"], rec["mag"], np.full(n, 0.01))
    np.testing.assert_array_equal(a["quat"], b["quat"])
    # float32 input is widened exactly
    f.reset()
    c = f.update_batch(rec["gyr"].astype(np.float32), rec["acc"].astype(np.float32), rec["mag"].astype(np.float32), 0.01)
    assert c["quat"].shape == (n, 4)


@pytest.mark.parametrize("chunk", [1, 2, 7, 500])
def test_sample_times_in_chunks_continue_the_stream(chunk):
    """A stream fed to update_batch in chunks of `t` runs as the whole array does (the step
    before a chunk's first sample is taken from the chunk before); the very first sample of
    a one-sample chunk has no step and is skipped, as one sample alone would be."""
    rec = rf.simulate("irregular-dt", seed=1, duration_s=20.0)
    whole = rf.Filter("flagship").update_batch(rec["gyr"], rec["acc"], rec["mag"], t=rec["t"])
    f = rf.Filter("flagship")
    parts = [
        f.update_batch(rec["gyr"][i:i + chunk], rec["acc"][i:i + chunk], rec["mag"][i:i + chunk], t=rec["t"][i:i + chunk])
        for i in range(0, len(rec["t"]), chunk)
    ]
    quat = np.concatenate([p["quat"] for p in parts])
    flags = np.concatenate([p["flags"] for p in parts])
    if chunk == 1:
        # The whole array takes t[1] - t[0] before sample 0; a stream of single samples
        # cannot know it: sample 0 alone is skipped (flag dt), every later one steps.
        # Sample 0's estimate is then the filter's state before any sample: scored from 1 on.
        assert flags[0] & rf.FLAG_DT and not np.any(flags[1:] & rf.FLAG_DT)
        later = dict(rec, use=np.arange(len(rec["t"])) > 0)
        assert rf.rmse(quat, later)["total"] < 1.1 * rf.rmse(whole["quat"], later)["total"]
    else:
        np.testing.assert_array_equal(quat, whole["quat"])
        np.testing.assert_array_equal(flags, whole["flags"])
    # dt ends the stream: the next call with t starts again from its own first step.
    f.update_batch(rec["gyr"][:3], rec["acc"][:3], rec["mag"][:3], 0.01)
    again = f.update_batch(rec["gyr"][:1], rec["acc"][:1], rec["mag"][:1], t=rec["t"][:1])
    assert again["flags"][0] & rf.FLAG_DT


def test_mostly_skipped_steps_warn_before_running():
    """Sample times passed as `dt` (positionally), times in ms: most steps are skipped, and
    update_batch says why, before it runs: a warning raised as an error leaves the filter as
    it was."""
    import warnings
    rec = rf.simulate("slow-rotation", seed=1, duration_s=20.0)
    g, a, m, t = rec["gyr"], rec["acc"], rec["mag"], rec["t"]
    with pytest.warns(UserWarning, match=r"skipped for their time step .*sample times go to `t=`"):
        rf.Filter("flagship").update_batch(g, a, m, t)
    with pytest.warns(UserWarning, match=r"divide ms by 1000"):
        rf.Filter("flagship").update_batch(g, a, m, t=t * 1000)
    f = rf.Filter("flagship")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserWarning):
            f.update_batch(g, a, m, t=t * 1000)
        assert f.rejections["dt"] == 0
        f.update_batch(g, a, m, t=t)  # no warning for a good call


def test_params_round_trip():
    """Filter(name, **f.params) rebuilds the same filter: whole-number parameters (dof,
    counts, switches) come back as ints."""
    for name in ["mahony", "flagship"]:
        f = rf.Filter(name, dof=6)
        p = f.params
        assert isinstance(p["dof"], int) and p["dof"] == 6
        assert rf.Filter(name, **p).params == p


def test_filters_listing_has_units():
    listing = rf.filters()
    assert {"sqrt-eskf", "mahony", "madgwick", "ekf", "gyro"} <= {f["name"] for f in listing}
    for f in listing:
        for p in f["params"]:
            assert {"name", "kind", "default", "unit", "min", "max", "doc"} <= set(p)
    assert rf.Filter("flagship").name == "sqrt-eskf"
    assert "Filter(" in repr(rf.Filter("gyro"))
    assert rf.Filter("gyro").dof is None


def test_build_info():
    info = rf.build_info()
    assert info["missing"] == []
    assert isinstance(info["compiled"], list)


def test_state_control():
    f = rf.Filter("sqrt-eskf", dof=6)
    a = np.radians(30.0)
    q = np.array([np.cos(a / 2), np.sin(a / 2), 0.0, 0.0])  # 30° roll
    f.set_quat(q * 2.0)  # normalised by the filter
    np.testing.assert_allclose(f.quat, q, atol=1e-12)
    # started from the set orientation, not from the accelerometer's
    g = np.zeros((1, 3)); acc = np.array([[0.0, 9.81 * np.sin(a), 9.81 * np.cos(a)]])
    f.update_batch(g, acc, None, 0.01)
    assert abs(np.degrees(2 * np.arccos(min(1.0, abs(float(f.quat @ q)))))) < 1.0
    f.set_heading(np.radians(90.0))
    w, x, y, z = f.quat
    heading = np.degrees(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    assert heading == pytest.approx(90.0, abs=1e-6)
    assert f.set_bias([0.01, -0.02, 0.0])
    np.testing.assert_allclose(f.bias, [0.01, -0.02, 0.0], atol=1e-12)
    assert not rf.Filter("complementary").set_bias([0.1, 0.0, 0.0])  # no bias estimate
    with pytest.raises(ValueError, match="q: expected 4 finite values"):
        f.set_quat([0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="bias: expected finite values"):
        f.set_bias([np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match="heading: expected a finite angle"):
        f.set_heading(float("inf"))


def test_forget_field_reference():
    # A still sensor whose magnetometer reads 20 % stronger from 1 s on because a calibration
    # changed: rejected as a disturbance unless the filter is told, then used at once.
    n, dip = 300, np.radians(64.0)
    g = np.zeros((n, 3)); a = np.tile([0.0, 0.0, 9.81], (n, 1))
    m = np.tile([0.0, 50 * np.cos(dip), -50 * np.sin(dip)], (n, 1))
    m[100:] *= 1.2
    disturbed = 64
    told, untold = rf.Filter("flagship", dof=9), rf.Filter("flagship", dof=9)
    for f in (told, untold):
        f.update_batch(g[:100], a[:100], m[:100], 0.01)
    told.forget_field_reference()
    flags_told = told.update_batch(g[100:], a[100:], m[100:], 0.01)["flags"]
    flags_untold = untold.update_batch(g[100:], a[100:], m[100:], 0.01)["flags"]
    assert not np.any(flags_told & disturbed)
    assert np.all(flags_untold[5:] & disturbed)  # after the 50 ms low-pass of the field
    rf.Filter("mahony").forget_field_reference()  # no reference: nothing happens
