"""The flagship beside VQF (the `vqf` package, its C++ core), run here on the same samples:
the simulated hard cases for inclination and the shared BROAD trials, online and offline; and
the flagship's covariance coverage on BROAD.

The goal (issue #35) is the flagship at or below VQF everywhere. Where it is not yet, the
ratio is pinned in KNOWN_BEHIND at what it is, so it cannot get worse unnoticed, and a pin
that the flagship has since beaten fails too, so the list stays true. The tables are
`benches/python/accuracy_peers.py` (docs/accuracy.md); this test uses its code.
"""

import os
import pathlib
import sys

import numpy as np
import pytest

import rootfuse as rf

try:
    import vqf  # noqa: F401 - the peer, run by accuracy_peers
except ImportError:
    if os.environ.get("CI"):
        raise  # scripts/test-all.sh installs it: under CI a missing peer fails
    pytest.skip("vqf absent (.venv/bin/pip install vqf==2.1.2): not compared", allow_module_level=True)

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "benches" / "python"))
import accuracy_peers as peers  # noqa: E402

# (data set, "online" | "offline", "total" | "inclination") -> largest ratio flagship / VQF
# allowed: the measured ratio (vqf 2.1.2, 5 seeds of 120 s, 100 Hz) plus about 2 %.
KNOWN_BEHIND: dict = {}


def ratios(rows):
    """{(data set, mode, metric): flagship / VQF} over the tables' rows."""
    out = {}
    for label, s in rows:
        for mode in ("online", "offline"):
            for i, metric in enumerate(("total", "inclination")):
                out[(label, mode, metric)] = s[f"flagship {mode}"][i] / s[f"VQF {mode}"][i]
    return out


def check(got):
    failures = []
    for key, ratio in sorted(got.items()):
        cap = KNOWN_BEHIND.get(key)
        if cap is None and ratio > 1.0:
            failures.append(f"{key}: {ratio:.3f} × VQF, behind it")
        elif cap is not None and ratio > cap:
            failures.append(f"{key}: {ratio:.3f} × VQF, worse than the pinned {cap}")
        elif cap is not None and ratio <= 1.0:
            failures.append(f"{key}: {ratio:.3f} × VQF, now level or ahead: remove it from KNOWN_BEHIND")
    return failures


def test_the_hard_cases_beside_vqf():
    got = ratios(peers.scenario_rows(5, 120.0))
    assert len(got) == 24
    failures = check(got)
    assert not failures, "\n".join(failures)


def test_broad_beside_vqf(broad_dir):
    rows = peers.broad_rows(broad_dir)
    assert [label for label, _ in rows] == ["BROAD, 14 trials, 9D", "BROAD, 14 trials, 6D"]
    failures = check(ratios(rows))
    assert not failures, "\n".join(failures)


def test_broad_covariance_coverage(broad_dir):
    # Mean over the 14 trials of the share of samples inside the 95 % ellipsoid (first 10 %
    # of each trial skipped). Measured: 9D total 0.892, with a 0.5° floor for the optical
    # truth's own error 0.970 (the goal is 0.90-0.98), inclination with the floor 0.960; 6D
    # total with the floor 0.931 (its heading's variance grows from 0 at the start,
    # init_heading_std).
    files = sorted(p for p in pathlib.Path(broad_dir).glob("*.csv") if p.name[:2].isdigit())
    assert len(files) == 14
    cover = {}
    for dof in (9, 6):
        for floor in (0.0, 0.5):
            cover[dof, floor] = []
        for p in files:
            rec = rf.read_csv(p)
            out = rf.Filter("flagship", dof=dof).update_batch(
                rec["gyr"], rec["acc"], rec["mag"] if dof == 9 else None, t=rec["t"]
            )
            for floor in (0.0, 0.5):
                c = rf.consistency(
                    out["quat"], out["covariance"], rec["truth"], use=rec.get("use"),
                    dof=dof, floor_deg=floor, skip=0.1,
                )
                cover[dof, floor].append((c["coverage_total"], c["coverage_inclination"]))
    mean = {k: np.mean(v, axis=0) for k, v in cover.items()}
    assert 0.87 <= mean[9, 0.0][0] <= 0.93, mean[9, 0.0]
    assert 0.95 <= mean[9, 0.5][0] <= 0.98, mean[9, 0.5]
    assert 0.95 <= mean[9, 0.5][1] <= 0.98, mean[9, 0.5]
    assert 0.92 <= mean[6, 0.5][0] <= 0.95, mean[6, 0.5]


def test_broad_constant_tilt_of_the_long_window(broad_dir):
    # docs/accuracy.md, "Where the online inclination still loses": the sensor's own constant
    # tilt is shared by every estimator (02: 0.21-0.23°, the flagship's 0.01-0.02° below VQF's
    # with the gyroscope's scale estimated), and on 16 and 31 the flagship's second window
    # adds one (measured 0.34 / 0.35° against 0.24 / 0.23° with one window). Pinned both
    # ways: a fix of it fails here until the page says so.
    import inclination_parts as parts_of

    found = {}
    for trial in ("02", "16", "31"):
        (path,) = pathlib.Path(broad_dir).glob(f"{trial}_*.csv")
        rec = rf.read_csv(path)
        est = parts_of.estimates(rec)
        used = rf.error_series(est["flagship"], rec, dof=6)["used"]
        found[trial] = {name: parts_of.parts(q, rec, used) for name, q in est.items()}
        for constant, varying, rms in found[trial].values():
            assert abs(constant ** 2 + varying ** 2 - rms ** 2) < 1e-9
    shared = [c[0] for c in found["02"].values()]
    assert max(shared) - min(shared) < 0.025, found["02"]
    for trial in ("16", "31"):
        added = found[trial]["flagship"][0] - found[trial]["one window"][0]
        assert 0.07 <= added <= 0.15, (trial, found[trial])


def test_broad_imu_lags_its_truth(broad_dir):
    # docs/accuracy.md, "BROAD's IMU samples lag its optical truth": against the truth taken
    # three quarters of a sample earlier, the flagship's and VQF's mean online inclination
    # both fall by about a quarter (measured 0.693 -> 0.525 and 0.725 -> 0.554), and a shift
    # twice that is worse again: an offset of the recording, shared by every estimator.
    # Smoothed, both fall by more than a third (measured 0.524 -> 0.326, VQF offline 0.529 ->
    # 0.320).
    import inclination_parts as parts_of

    files = sorted(p for p in pathlib.Path(broad_dir).glob("*.csv") if p.name[:2].isdigit())
    assert len(files) == 14
    found = {}
    for p in files:
        rec = rf.read_csv(p)
        est = dict(parts_of.estimates(rec), **parts_of.offline_estimates(rec))
        for shift in (0.0, 0.75, 1.5):
            shifted = dict(rec, truth=parts_of.truth_earlier(rec["truth"], shift))
            for name in ("flagship", "VQF online", "flagship offline", "VQF offline"):
                found.setdefault((name, shift), []).append(
                    rf.rmse(est[name], shifted, dof=6)["inclination"]
                )
    mean = {k: float(np.mean(v)) for k, v in found.items()}
    for name in ("flagship", "VQF online"):
        assert mean[name, 0.75] < 0.8 * mean[name, 0.0], mean
        assert mean[name, 0.75] < mean[name, 1.5], mean
    gain = [mean[n, 0.0] - mean[n, 0.75] for n in ("flagship", "VQF online")]
    assert abs(gain[0] - gain[1]) < 0.02, mean
    for name in ("flagship offline", "VQF offline"):
        assert mean[name, 0.75] < 0.7 * mean[name, 0.0], mean


def test_broad_gyroscope_scale_factor(broad_dir):
    # docs/accuracy.md, "BROAD's gyroscope scale factor": the 6D heading drift of the trials
    # that turn one way many times is a steady fraction of that rotation (measured 0.33-0.56 %
    # on 04, 08, 29, 31 and of the other sign on 33, 35), and the gyroscope multiplied by
    # 1.002 takes the flagship's and VQF's 6D total (2.393 -> 1.899, 2.406 -> 1.894) and
    # inclination (0.722 -> 0.650, 0.725 -> 0.628) down alike, their 9D up (2.051 -> 2.203,
    # 2.212 -> 2.306): the recording's sensor, not a filter. The flagship without its own
    # estimate of the scale (gyro_scale.FLAGSHIP), as the page measures it.
    import gyro_scale

    files = sorted(p for p in pathlib.Path(broad_dir).glob("*.csv") if p.name[:2].isdigit())
    assert len(files) == 14
    ratio, errors = {}, {}
    for p in files:
        rec = rf.read_csv(p)
        if p.name[:2] in ("04", "08", "29", "31", "33", "35"):
            q6 = rf.Filter("flagship", dof=6, **gyro_scale.FLAGSHIP).update_batch(
                rec["gyr"], rec["acc"], None, t=rec["t"]
            )["quat"]
            ratio[p.name[:2]] = gyro_scale.heading_drift(q6, rec) / gyro_scale.net_vertical_rotation(rec["truth"])
        for factor in (1.0, 1.002):
            for name, e in gyro_scale.errors(rec, (factor,) * 3).items():
                errors.setdefault((name, factor), []).append(e)
    for trial in ("04", "08", "29", "31"):
        assert 0.002 < ratio[trial] < 0.007, ratio
    for trial in ("33", "35"):
        assert 0.003 < -ratio[trial] < 0.007, ratio
    mean = {k: np.mean(v, axis=0) for k, v in errors.items()}
    for name in ("flagship", "VQF online"):
        nine_d, six_d, inclination = mean[name, 1.002] / mean[name, 1.0]
        assert six_d < 0.85 and inclination < 0.92 and nine_d > 1.03, (name, mean)
