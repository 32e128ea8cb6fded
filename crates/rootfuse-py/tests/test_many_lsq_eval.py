"""Many channels, least squares, metrics, simulator and recordings: every public function at
least once, with results checked against single-channel runs, closed forms or the Rust CLI."""

import numpy as np
import pytest

import rootfuse as rf


def sims(count, duration_s=1.0):
    return [rf.simulate("slow-rotation", seed=s, duration_s=duration_s, rate_hz=100.0) for s in range(count)]


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_run_many_stacked_equals_single_channels(precision):
    recs = sims(11)  # not a multiple of the lane width
    gyr = np.stack([r["gyr"] for r in recs])
    acc = np.stack([r["acc"] for r in recs])
    mag = np.stack([r["mag"] for r in recs])
    gyr[3, 7] = np.nan
    out = rf.run_many("sqrt-eskf", gyr, acc, mag, 0.01, precision=precision, covariance=True)
    assert out["quat"].shape == (11, 101, 4) or out["quat"].shape[:2] == gyr.shape[:2]
    for c in range(11):
        single = rf.Filter("sqrt-eskf", precision=precision).update_batch(gyr[c], acc[c], mag[c], 0.01)
        np.testing.assert_array_equal(out["quat"][c], single["quat"])
        np.testing.assert_array_equal(out["bias"][c], single["bias"])
        np.testing.assert_array_equal(out["covariance"][c], single["covariance"])
        np.testing.assert_array_equal(out["flags"][c], single["flags"])
    assert out["flags"][3, 7] & rf.FLAG_GYR
    assert out["rejections"][3]["gyr"] == 1


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_run_many_views_of_one_array_equal_the_stacked_array(dtype):
    """A list of channels cut from one array: past the first views of a base the channels are
    copied instead of borrowed (borrowing every view costs the square of their number); the
    results are those of the stacked array, bit for bit."""
    recs = sims(40, duration_s=0.3)
    gyr = np.stack([r["gyr"] for r in recs]).astype(dtype)
    acc = np.stack([r["acc"] for r in recs]).astype(dtype)
    mag = np.stack([r["mag"] for r in recs]).astype(dtype)
    gyr[29, 3] = np.nan
    for series in (False, True):
        stacked = rf.run_many("madgwick", gyr, acc, mag, 0.01, series=series)
        views = rf.run_many("madgwick", list(gyr), list(acc), list(mag), 0.01, series=series)
        if series:
            views = {"quat": np.stack([v["quat"] for v in views]),
                     "rejections": [v["rejections"] for v in views]}
        np.testing.assert_array_equal(views["quat"], stacked["quat"])
        assert views["rejections"] == stacked["rejections"]
        assert views["rejections"][29]["gyr"] == 1


@pytest.mark.parametrize("series", [False, True])
def test_run_many_rejections_are_each_channels_own(series):
    """Each channel's counts in its own dict, the keys of Filter.rejections in their order
    (the dicts are copies of one all-zero dict: none shares it, none changes it)."""
    recs = sims(5)
    gyr = np.stack([r["gyr"] for r in recs])
    acc = np.stack([r["acc"] for r in recs])
    gyr[1, 4] = np.nan
    acc[2, 5:8] = 0.0
    single = rf.Filter("mahony", dof=6)
    single.update_batch(gyr[0], acc[0], None, 0.01)
    for _ in range(2):  # the second run after the first one's dicts were changed
        rej = rf.run_many("mahony", gyr, acc, None, 0.01, dof=6, series=series)["rejections"]
        assert [list(r) for r in rej] == [list(single.rejections)] * 5
        assert [(r["dt"], r["gyr"], r["acc"]) for r in rej] == [(0, 0, 0), (0, 1, 0), (0, 0, 3), (0, 0, 0), (0, 0, 0)]
        assert len({id(r) for r in rej}) == 5
        rej[0]["dt"] = 99
        assert rej[3]["dt"] == 0


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_run_many_float32_series(precision):
    """dtype float32: the float64 series rounded to float32 (with f32 lanes exactly them),
    for stacked and list input; flags and counts as they are; a dtype that is not a float
    type is refused by name."""
    recs = sims(11)
    gyr = np.stack([r["gyr"] for r in recs]); acc = np.stack([r["acc"] for r in recs])
    mag = np.stack([r["mag"] for r in recs])
    gyr[3, 7] = np.nan
    wide = rf.run_many("sqrt-eskf", gyr, acc, mag, 0.01, precision=precision, covariance=True)
    for dtype in ("float32", np.float32):
        narrow = rf.run_many("sqrt-eskf", gyr, acc, mag, 0.01, precision=precision, covariance=True,
                             dtype=dtype)
        for key in ("quat", "bias", "covariance"):
            assert narrow[key].dtype == np.float32 and narrow[key].shape == wide[key].shape
            np.testing.assert_array_equal(narrow[key], wide[key].astype(np.float32))
            if precision == "f32":
                np.testing.assert_array_equal(narrow[key].astype(np.float64), wide[key])
        np.testing.assert_array_equal(narrow["flags"], wide["flags"])
        assert narrow["rejections"] == wide["rejections"]
    listed = rf.run_many("mahony", list(gyr[:3]), list(acc[:3]), None, 0.01, dtype="float32")
    assert [c["quat"].dtype for c in listed] == [np.float32] * 3
    same = rf.run_many("sqrt-eskf", gyr, acc, mag, 0.01, precision=precision, dtype=np.float64)
    np.testing.assert_array_equal(same["quat"], wide["quat"])
    with pytest.raises(TypeError, match=r"dtype: expected \"float32\" or \"float64\".*int16"):
        rf.run_many("mahony", gyr, acc, None, 0.01, dtype="int16")


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_run_many_into_given_arrays(dtype):
    """out=: the series written into the caller's arrays, the same values as new ones, every
    element overwritten (the arrays start as garbage), on every reuse; wrong shapes, types,
    keys, read-only or input-sharing arrays are refused by name before anything is written."""
    recs = sims(11)
    gyr = np.stack([r["gyr"] for r in recs]); acc = np.stack([r["acc"] for r in recs])
    mag = np.stack([r["mag"] for r in recs])
    gyr[3, 7] = np.nan
    C, N = gyr.shape[:2]
    new = rf.run_many("sqrt-eskf", gyr, acc, mag, 0.01, covariance=True, dtype=dtype)
    out = {"quat": np.full((C, N, 4), 7.0, dtype), "bias": np.full((C, N, 3), 7.0, dtype),
           "covariance": np.full((C, N, 3, 3), 7.0, dtype), "flags": np.full((C, N), 255, np.uint8)}
    for _ in range(2):
        got = rf.run_many("sqrt-eskf", gyr, acc, mag, 0.01, covariance=True, out=out)
        for key in ("quat", "bias", "covariance", "flags"):
            assert got[key] is out[key]
            np.testing.assert_array_equal(out[key], new[key])
        assert got["rejections"] == new["rejections"]
    # Only the series asked for are needed; the quaternions of a 6D Mahony run.
    quat = np.empty((C, N, 4), dtype)
    got = rf.run_many("mahony", gyr, acc, None, 0.01, bias=False, flags=False, out={"quat": quat})
    np.testing.assert_array_equal(quat, rf.run_many("mahony", gyr, acc, None, 0.01, dtype=dtype)["quat"])
    other = np.float32 if dtype == np.float64 else np.float64
    before = quat.copy()
    bad = [
        ({"quat": np.empty((C, N + 1, 4), dtype)}, ValueError, r"out\[\"quat\"\]: .*shape \[11, 101, 4\]"),
        ({"quat": np.empty((C, N, 4), np.int32)}, TypeError, r"out\[\"quat\"\]: expected a float32 or float64"),
        ({"quat": quat, "bias": np.empty((C, N, 3), other)}, TypeError, r"out\[\"bias\"\]: expected a"),
        ({"quat": quat}, ValueError, r"out: missing \"bias\".*bias=False"),
        ({"quat": quat, "bias": np.empty((C, N, 3), dtype), "flag": 1}, ValueError, r"unknown key \"flag\""),
        ({"quat": np.empty((C, 4, N), dtype).transpose(0, 2, 1)}, ValueError, r"not C-contiguous"),
        ([quat], TypeError, r"out: expected a dict"),
    ]
    for given, error, message in bad:
        with pytest.raises(error, match=message):
            rf.run_many("mahony", gyr, acc, None, 0.01, flags=False, out=given)
    frozen = np.empty((C, N, 4), dtype); frozen.flags.writeable = False
    with pytest.raises(ValueError, match=r"out: an array cannot be written"):
        rf.run_many("mahony", gyr, acc, None, 0.01, bias=False, flags=False, out={"quat": frozen})
    # An output sharing memory with an input: refused, the input untouched.
    memory = np.zeros(C * N * 4, dtype)
    memory[: C * N * 3] = gyr.ravel()
    shared = memory[: C * N * 3].reshape(C, N, 3)
    with pytest.raises(ValueError, match=r"out\[\"quat\"\]: shares memory with gyr"):
        rf.run_many("mahony", shared, acc, None, 0.01, bias=False, flags=False,
                    out={"quat": memory.reshape(C, N, 4)})
    np.testing.assert_array_equal(shared, gyr.astype(dtype))
    # Two buffers over the same memory (NumPy's borrow tracking sees only one base object).
    raw = bytearray(C * N * 4 * np.dtype(dtype).itemsize)
    with pytest.raises(ValueError, match=r"out\[\"quat\"\]: shares memory with gyr"):
        rf.run_many("mahony", np.frombuffer(memoryview(raw)[: C * N * 3 * np.dtype(dtype).itemsize], dtype).reshape(C, N, 3),
                    acc, None, 0.01, bias=False, flags=False,
                    out={"quat": np.frombuffer(raw, dtype).reshape(C, N, 4)})
    # Sample times as a (C, N) float64 array are read in place, as the sensors are: an output
    # over their memory is refused too.
    raw = bytearray(C * N * 4 * np.dtype(dtype).itemsize)
    times = np.frombuffer(raw, np.float64, count=C * N).reshape(C, N)
    times[:] = np.arange(N) * 0.01
    with pytest.raises(ValueError, match=r"out\[\"quat\"\]: shares memory with t"):
        rf.run_many("mahony", gyr, acc, None, t=times, bias=False, flags=False,
                    out={"quat": np.frombuffer(raw, dtype).reshape(C, N, 4)})
    np.testing.assert_array_equal(times, np.broadcast_to(np.arange(N) * 0.01, (C, N)))
    both = np.empty((C, N, 4), dtype)
    with pytest.raises(ValueError, match=r"shares memory with out\[\"bias\"\]"):
        rf.run_many("mahony", gyr, acc, None, 0.01, flags=False,
                    out={"quat": both, "bias": both[:, :, :3]})
    # Memory not aligned for the float type: refused, not written through.
    unaligned = np.frombuffer(bytearray(C * N * 4 * np.dtype(dtype).itemsize + 1), dtype,
                              count=C * N * 4, offset=1).reshape(C, N, 4)
    with pytest.raises(ValueError, match=r"not aligned"):
        rf.run_many("mahony", gyr, acc, None, 0.01, bias=False, flags=False, out={"quat": unaligned})
    # A key for a series the call does not compute would keep stale values: refused.
    with pytest.raises(ValueError, match=r"out: has \"flags\", a series this call does not compute"):
        rf.run_many("mahony", gyr, acc, None, 0.01, bias=False, flags=False,
                    out={"quat": quat, "flags": np.empty((C, N), np.uint8)})
    with pytest.raises(ValueError, match=r"dtype: differs from out"):
        rf.run_many("mahony", gyr, acc, None, 0.01, bias=False, flags=False, dtype=other, out={"quat": quat})
    with pytest.raises(ValueError, match=r"series=False"):
        rf.run_many("mahony", gyr, acc, None, 0.01, series=False, out={"quat": quat})
    with pytest.raises(TypeError, match=r"not lists"):
        rf.run_many("mahony", list(gyr), list(acc), None, 0.01, bias=False, flags=False, out={"quat": quat})
    np.testing.assert_array_equal(quat, before)


def test_run_many_lists_of_different_lengths_and_channel_params():
    recs = [rf.simulate("fast-rotation", seed=s, duration_s=0.5 + 0.25 * s) for s in range(5)]
    params = [{"kp": 0.5 + 0.1 * c} for c in range(5)]
    out = rf.run_many("mahony", [r["gyr"] for r in recs], [r["acc"] for r in recs], [r["mag"] for r in recs],
                      t=[r["t"] for r in recs], precision="f64", channel_params=params, ki=0.01)
    assert isinstance(out, list) and len(out) == 5
    for c, r in enumerate(recs):
        single = rf.Filter("mahony", kp=params[c]["kp"], ki=0.01).update_batch(r["gyr"], r["acc"], r["mag"], t=r["t"])
        assert out[c]["quat"].shape == (len(r["t"]), 4)
        np.testing.assert_array_equal(out[c]["quat"], single["quat"])
        np.testing.assert_array_equal(out[c]["flags"], single["flags"])


@pytest.mark.parametrize("precision", ["f32", "f64"])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_run_many_quaternion_only_series_of_different_lengths(precision, dtype):
    """The quaternion-only series (every lane of a step moved at once, transposed in
    registers) equal the full series bit for bit: full chunks, a partial one, and lanes
    that end at different steps."""
    recs = [rf.simulate("fast-rotation", seed=s, duration_s=0.3 + 0.11 * s) for s in range(19)]
    args = ([r["gyr"] for r in recs], [r["acc"] for r in recs], [r["mag"] for r in recs])
    t = [r["t"] for r in recs]
    quat_only = rf.run_many("madgwick", *args, t=t, precision=precision, dtype=dtype, bias=False, flags=False)
    full = rf.run_many("madgwick", *args, t=t, precision=precision, dtype=dtype)
    for q, f, r in zip(quat_only, full, recs):
        assert q["quat"].shape == (len(r["t"]), 4) and q["quat"].dtype == np.dtype(dtype)
        np.testing.assert_array_equal(q["quat"], f["quat"])


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_run_many_without_mag_and_fixed_steps_over_many_tiles(precision):
    """6D data into a filter that is 9D by default, with a fixed step: the engine writes the
    NaN field and the step into a channel's lane once and skips those stores in later tiles;
    every channel still equals its own run, its missing magnetometer counted at every sample,
    across tiles, channels of different lengths and lanes that fall idle."""
    recs = [rf.simulate("fast-rotation", seed=s, duration_s=0.6 + 0.17 * s, rate_hz=100.0) for s in range(19)]
    out = rf.run_many("mahony", [r["gyr"] for r in recs], [r["acc"] for r in recs], None, 0.01,
                      precision=precision)
    for c, r in enumerate(recs):
        single = rf.Filter("mahony", precision=precision).update_batch(r["gyr"], r["acc"], None, 0.01)
        np.testing.assert_array_equal(out[c]["quat"], single["quat"], err_msg=f"channel {c}")
        np.testing.assert_array_equal(out[c]["flags"], single["flags"], err_msg=f"channel {c}")
        assert out[c]["rejections"]["mag"] == len(r["t"])
        assert out[c]["rejections"]["dt"] == 0


def test_run_many_final_states_only():
    recs = sims(9)
    gyr = np.stack([r["gyr"] for r in recs]); acc = np.stack([r["acc"] for r in recs])
    dt = np.full(gyr.shape[:2], 0.01)
    full = rf.run_many("madgwick", gyr, acc, None, dt, dof=6)
    final = rf.run_many("madgwick", gyr, acc, None, dt, dof=6, series=False,
                        channel_params=[{"beta": 0.1}] * 9)
    assert final["quat"].shape == (9, 4)
    other = rf.run_many("madgwick", gyr, acc, None, dt, dof=6, series=False, beta=0.1)
    np.testing.assert_array_equal(final["quat"], other["quat"])
    plain = rf.run_many("madgwick", gyr, acc, None, dt, dof=6, series=False)
    np.testing.assert_array_equal(plain["quat"], full["quat"][:, -1])
    np.testing.assert_array_equal(plain["bias"], full["bias"][:, -1])


@pytest.mark.parametrize("name", ["mahony", "sqrt-eskf"])
@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_run_many_float32_input_is_read_as_is(name, precision):
    """float32 arrays are read without a widening copy: the same bits as the same values given
    as float64, in lanes (mahony runs two vectors interleaved) and alone (update_batch)."""
    recs = sims(11, duration_s=1.5)  # 151 samples: several full tiles and a partial one
    g32 = np.stack([r["gyr"] for r in recs]).astype(np.float32)
    a32 = np.stack([r["acc"] for r in recs]).astype(np.float32)
    m32 = np.stack([r["mag"] for r in recs]).astype(np.float32)
    g32[4, 70] = np.nan
    wide = [x.astype(np.float64) for x in (g32, a32, m32)]
    for series in (True, False):
        a = rf.run_many(name, g32, a32, m32, 0.01, precision=precision, series=series)
        b = rf.run_many(name, *wide, 0.01, precision=precision, series=series)
        np.testing.assert_array_equal(a["quat"], b["quat"])
        np.testing.assert_array_equal(a["bias"], b["bias"])
    single = rf.Filter(name, precision=precision).update_batch(g32[4], a32[4], m32[4], 0.01)
    np.testing.assert_array_equal(a["quat"][4], single["quat"][-1])
    assert a["rejections"][4]["gyr"] == 1


def test_run_many_channels_across_tiles_and_outputs_not_asked():
    """Channels of 1, 63, 64, 65 and 200 samples (around the engine's 64-step tiles), each
    equal to its own run; series nobody asked for are not in the result."""
    lens = [1, 63, 64, 65, 200]
    recs = [rf.simulate("fast-rotation", seed=s, duration_s=2.0) for s in range(len(lens))]
    gyr = [r["gyr"][:n] for r, n in zip(recs, lens)]
    acc = [r["acc"][:n] for r, n in zip(recs, lens)]
    out = rf.run_many("madgwick", gyr, acc, None, 0.01, dof=6, precision="f64", bias=False,
                      flags=False)
    for c, n in enumerate(lens):
        assert set(out[c]) == {"quat", "rejections"}
        single = rf.Filter("madgwick", dof=6).update_batch(gyr[c], acc[c], None, 0.01)
        np.testing.assert_array_equal(out[c]["quat"], single["quat"])
    many = rf.run_many("mahony", np.stack(gyr[2:4:2] * 3), np.stack(acc[2:4:2] * 3), None, 0.01, dof=6,
                       covariance=True)
    assert "covariance" not in many  # Mahony carries none


@pytest.mark.parametrize("form", rf.rls_forms())
@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_rls_fits_a_line(form, precision):
    t = np.linspace(0.0, 1.0, 200)
    h = np.stack([np.ones_like(t), t], axis=1)
    z = 2.0 + 3.0 * t
    r = rf.Rls(form, 2, p0=1e4, precision=precision)
    out = r.run(h, z)
    # closed form of the same problem: prior x0 = 0, P0 = 1e4 I
    exact = np.linalg.solve(np.eye(2) / 1e4 + h.T @ h, h.T @ z)
    tol = 1e-3 if precision == "f32" else 1e-9
    np.testing.assert_allclose(out["estimate"][-1], exact, atol=tol)
    np.testing.assert_allclose(out["estimate"][-1], [2.0, 3.0], atol=1e-3)
    assert out["estimate"].shape == (200, 2) and out["accepted"].all()
    assert not out["lost_definiteness"].any()
    np.testing.assert_array_equal(r.estimate, out["estimate"][-1])
    assert r.covariance.shape == (2, 2) and r.health["accepted"] == 200
    assert r.form == form and r.n == 2 and r.precision == precision and form in repr(r)
    # sample by sample gives the same bits as the array run
    s = rf.Rls(form, 2, p0=1e4, precision=precision)
    for i in range(200):
        assert s.update(h[i], z[i], 1.0)
    np.testing.assert_array_equal(s.estimate, r.estimate)


def test_rls_forgetting_bounds_and_every_size():
    for n in range(1, 9):
        r = rf.Rls("inverse-qr", n, lam=0.99, p0=1e3, p_min=1e-6, p_max=1e3)
        h = np.random.default_rng(n).standard_normal((300, n))
        x = np.arange(1.0, n + 1.0)
        out = r.run(h, h @ x, 1.0)
        # the prior's weight has decayed to 0.99^300 / 1e3 and the upper bound adds about
        # 1/p_max of information, against about 100 from the data
        np.testing.assert_allclose(out["estimate"][-1], x, rtol=1e-4)
    # windup: only the first regressor excited; the bound keeps P below p_max
    r = rf.Rls("bierman-ud", 2, lam=0.9, p0=1.0, p_min=0.0, p_max=10.0)
    r.run(np.tile([1.0, 0.0], (500, 1)), np.ones(500))
    assert np.linalg.eigvalsh(r.covariance).max() <= 10.0 * (1 + 1e-9)
    r2 = rf.Rls("information-qr", 2, x0=np.array([1.0, 1.0]), p0=np.eye(2), compensated=False)
    assert r2.estimate.tolist() == [1.0, 1.0]


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_potter_predict_is_the_known_transition(precision):
    # Closed form: x ← F x, P ← F P Fᵀ / λ.
    x0 = np.array([1.0, -2.0, 0.5])
    p0 = np.array([[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 0.5]])
    f = np.array([[1.0, 0.1, 0.005], [0.0, 1.0, 0.1], [0.0, 0.0, 1.0]])
    r = rf.Rls("potter", 3, x0=x0, p0=p0, precision=precision)
    assert r.predict(f, lam=0.9)
    tol = 1e-5 if precision == "f32" else 1e-12
    np.testing.assert_allclose(r.estimate, f @ x0, rtol=tol, atol=tol)
    np.testing.assert_allclose(r.covariance, f @ p0 @ f.T / 0.9, rtol=tol, atol=tol)
    # A bad transition is refused and counted, the state kept.
    before = r.estimate.copy()
    assert not r.predict(np.full((3, 3), np.nan))
    np.testing.assert_array_equal(r.estimate, before)
    assert r.health["rejected_input"] == 1
    with pytest.raises(ValueError, match="only the potter form"):
        rf.Rls("bierman-ud", 3).predict(f)
    with pytest.raises(ValueError, match="bounds"):
        rf.Rls("potter", 3, p0=1.0, p_max=10.0).predict(f)


def test_bierman_time_update_adds_process_noise():
    p0 = np.array([[2.0, 0.3], [0.3, 1.0]])
    r = rf.Rls("bierman-ud", 2, p0=p0)
    q = np.array([0.5, 0.25])
    assert r.time_update(q)
    np.testing.assert_allclose(r.covariance, p0 + np.diag(q), rtol=1e-12, atol=1e-12)
    assert not r.time_update(np.array([-1.0, 0.0]))
    np.testing.assert_allclose(r.covariance, p0 + np.diag(q), rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="only the bierman-ud form"):
        rf.Rls("potter", 2).time_update(q)
    with pytest.raises(ValueError, match="q: expected"):
        r.time_update(np.zeros(3))


def test_conventional_form_flags_its_failure_in_f32():
    # Dyer-McReynolds, delta = 1e-4 in f32: the covariance forms lose definiteness and say so
    d = 1e-4
    rows = np.array([[1.0, 1.0, 1.0], [1.0, 1.0, 1.0 + d]] * 3)
    for form in ("conventional", "potter"):
        r = rf.Rls(form, 3, p0=1.0, precision="f32")
        out = r.run(rows, np.zeros(len(rows)), 1.0 / d**2)
        if form == "conventional":
            assert out["lost_definiteness"].any() or not out["accepted"].all()
        else:
            assert out["accepted"].all() and (out["min_pivot"] > 0).all()


@pytest.mark.parametrize("method", ["qr", "pivoted-qr", "svd", "normal-equations"])
def test_lstsq_methods(method):
    rng = np.random.default_rng(0)
    h = rng.standard_normal((50, 3))
    x = np.array([1.0, -2.0, 0.5])
    z = h @ x + 1e-3 * rng.standard_normal(50)
    sol = rf.lstsq(h, z, method=method)
    ref = np.linalg.lstsq(h, z, rcond=None)[0]
    np.testing.assert_allclose(sol["estimate"], ref, rtol=1e-10)
    assert sol["rank"] == 3 and sol["dof"] == 47 and sol["covariance"].shape == (3, 3)
    w = rng.uniform(0.5, 2.0, 50)
    sw = rf.lstsq(h, z, weights=w, method=method)
    refw = np.linalg.lstsq(h * np.sqrt(w)[:, None], z * np.sqrt(w), rcond=None)[0]
    np.testing.assert_allclose(sw["estimate"], refw, rtol=1e-10)
    sc = rf.lstsq(h, z, covariance=np.diag(1.0 / w), method=method)
    np.testing.assert_allclose(sc["estimate"], refw, rtol=1e-10)
    s32 = rf.lstsq(h, z, method=method, precision="f32")
    np.testing.assert_allclose(s32["estimate"], ref, rtol=1e-4)


def test_lstsq_normal_equations_report_breakdown():
    # Läuchli: H^T H is singular in f64 for eps = 1e-9; QR solves it, normal equations say so
    e = 1e-9
    h = np.array([[1.0, 1.0], [e, 0.0], [0.0, e]])
    z = np.array([2.0, e, e])
    np.testing.assert_allclose(rf.lstsq(h, z, method="qr")["estimate"], [1.0, 1.0], rtol=1e-6)
    with pytest.raises(ValueError, match="normal equations"):
        rf.lstsq(h, z, method="normal-equations")
    sol = rf.lstsq(np.ones((4, 2)), np.ones(4), method="pivoted-qr")
    assert sol["rank"] == 1


def test_stress_rows():
    assert "dyer-mcreynolds" in rf.stress_scenarios()
    rows = rf.stress("dyer-mcreynolds", scale=0.01)
    assert {r["form"] for r in rows} == set(rf.rls_forms())
    assert {r["precision"] for r in rows} == {"f32", "f64"}
    for r in rows:
        assert set(r) >= {"scenario", "param", "steps", "max_rel_err", "pd_lost_at", "nan_at", "detected", "ns_per_update", "trace"}
    # f32, delta = 1e-4: the conventional form is flagged, Bierman U-D is accurate (the table in docs/numerics.md)
    pick = {(r["form"], r["precision"], r["param"]): r for r in rows}
    assert pick[("conventional", "f32", 1e-4)]["detected"]
    assert pick[("bierman-ud", "f32", 1e-4)]["max_rel_err"] < 1e-2


def test_metrics_closed_forms():
    n = 100
    truth = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    a = np.radians(10.0)
    est = np.tile([np.cos(a / 2), 0.0, 0.0, np.sin(a / 2)], (n, 1))  # 10° heading error
    r9 = rf.rmse(est, truth)
    assert r9["total"] == pytest.approx(10.0) and r9["heading"] == pytest.approx(10.0)
    assert r9["inclination"] == pytest.approx(0.0, abs=1e-9) and r9["n_used"] == n
    r6 = rf.rmse(est, truth, dof=6)  # constant heading offset removed
    assert r6["total"] == pytest.approx(0.0, abs=1e-9) and r6["heading_offset"] == pytest.approx(10.0)
    assert rf.heading_offset(est, truth) == pytest.approx(10.0)
    use = np.zeros(n, dtype=bool); use[:10] = True
    assert rf.rmse(est, truth, use=use)["n_used"] == 10
    s = rf.error_series(est, truth, dof=9)
    np.testing.assert_allclose(s["total"], 10.0)
    assert s["used"].all()


def test_simulator_and_recordings_roundtrip(tmp_path):
    assert "static" in rf.scenario_names()
    rec = rf.simulate("translation", seed=7, duration_s=2.0, rate_hz=50.0)
    assert rec["gyr"].shape == (100, 3) and rec["truth"].shape == (100, 4)
    path = tmp_path / "rec.csv"
    rf.write_recording(path, rec["t"], rec["gyr"], rec["acc"], rec["mag"], truth=rec["truth"], use=rec["use"])
    back = rf.read_csv(path)
    for k in ("t", "gyr", "acc", "mag", "truth", "use"):
        np.testing.assert_array_equal(back[k], rec[k])
    est = rf.Filter("sqrt-eskf").update_batch(back["gyr"], back["acc"], back["mag"], t=back["t"])
    out = tmp_path / "est.csv"
    rf.write_estimates(out, back["t"], est["quat"], {"flags": est["flags"].astype(float)})
    again = rf.read_estimates(out)
    np.testing.assert_array_equal(again["quat"], est["quat"])
    np.testing.assert_array_equal(again["t"], back["t"])
    assert rf.rmse(est["quat"], back["truth"], use=back["use"])["total"] < 10.0
    # A recording in place of the truth scores what `rootfuse eval` scores: its truth and use.
    assert rf.rmse(est["quat"], back) == rf.rmse(est["quat"], back["truth"], use=back["use"])


def test_rmse_refuses_what_eval_refuses():
    """An estimate that counts must be a unit quaternion: an all-zero row would score as
    perfect, 2q would be normalised silently, a NaN row gives a NaN RMSE. Rows the use mask
    leaves out are not checked."""
    n = 20
    truth = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    for bad, norm in ((np.zeros(4), "0"), (2 * truth[0], "2"), (np.full(4, np.nan), "NaN")):
        est = truth.copy()
        est[7] = bad
        with pytest.raises(ValueError, match=f"estimate row 7: norm {norm} is not 1"):
            rf.rmse(est, truth)
        use = np.ones(n, dtype=bool); use[7] = False
        assert rf.rmse(est, truth, use=use)["n_used"] == n - 1
    with pytest.raises(ValueError, match="no ground truth"):
        rf.rmse(truth, {"truth": None, "use": None})


def test_consistency_matches_a_closed_form_and_the_flagship():
    # Errors of exactly one standard deviation about x: NEES/3 = 1/3, all inside.
    n = 40
    truth = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    half = 0.005
    est = np.tile([np.cos(half), np.sin(half), 0.0, 0.0], (n, 1))
    cov = np.tile(np.eye(3) * 1e-4, (n, 1, 1))
    c = rf.consistency(est, cov, truth, skip=0.0)
    assert abs(c["nees_total"] - 1.0 / 3.0) < 1e-9
    assert c["coverage_total"] == 1.0 and c["n_used"] == n
    upper = np.tile([1e-4, 0, 0, 1e-4, 0, 1e-4], (n, 1))
    assert rf.consistency(est, upper, truth, skip=0.0) == c
    # A floor widens the ellipsoid: NEES falls.
    assert rf.consistency(est, cov, truth, skip=0.0, floor_deg=1.0)["nees_total"] < c["nees_total"]
    # The flagship on a simulated recording: finite figures, samples counted.
    rec = rf.simulate("slow-rotation", seed=1, duration_s=20.0)
    out = rf.Filter("sqrt-eskf").update_batch(rec["gyr"], rec["acc"], rec["mag"], 0.01)
    r = rf.consistency(out["quat"], out["covariance"], rec)
    assert np.isfinite(r["nees_total"]) and 0.0 < r["coverage_total"] <= 1.0
    assert r["n_used"] > 0.8 * len(rec["t"])
    for bad, msg in [
        (dict(cov=cov[:, :2, :2]), "cov: expected shape"),
        (dict(cov=cov[:-1]), "cov: has 39 samples"),
        (dict(cov=cov, floor_deg=-1.0), "floor_deg"),
        (dict(cov=cov, skip=1.0), "skip"),
    ]:
        with pytest.raises(ValueError, match=msg):
            rf.consistency(est, truth=truth, **bad)
