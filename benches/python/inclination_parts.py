"""Where online inclination error comes from, trial by trial: the part that stays constant in
the sensor frame and the part that varies, for the flagship (6D, its defaults and with one
accelerometer window) and for VQF online (the `vqf` package), on the shared BROAD trials.

    .venv/bin/python benches/python/inclination_parts.py [--broad DIR] [--docs docs/accuracy.md]

The inclination error of a sample is the small rotation between the estimated and the true
up direction in the sensor frame, `d = up_est × up_true` (degrees; its norm is the angle). Over
the samples the BROAD metric counts, its mean `m` is the constant part, and `rms² = |m|² +
varying²` splits the RMSE: a constant tilt that two filters share is the sensor's own (an
accelerometer offset or misalignment against the optical frame), one that differs is made by
the filter. With `--docs` the table replaces the text between `<!-- inclination_parts:begin -->`
and `<!-- inclination_parts:end -->` in that file.

A second table scores the same estimates (the flagship's defaults and VQF online), and both
smoothed (`rootfuse.smooth` and `offlineVQF`, 6D), against the optical truth taken a fraction
of a sample earlier (`truth_earlier`): where the filters gain alike, the recording's IMU samples lag its optical truth by that much, which no estimator can
tell from the IMU alone. It goes between `<!-- inclination_time_offset:begin -->` and
`<!-- inclination_time_offset:end -->`.
"""

import platform
import sys

import numpy as np

import docs_page
import rootfuse as rf
from accuracy_peers import VQF_VERSION, broad_parser, broad_trials

try:
    import vqf
except ImportError:  # a bench, not a test: say what is missing and stop
    sys.exit("vqf is not installed: .venv/bin/pip install vqf")



def up_in_sensor(q):
    """Earth-up in the sensor frame of sensor-to-earth quaternions `[w, x, y, z]` (N, 4)."""
    w, x, y, z = q.T
    return np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)


def parts(quat, rec, used):
    """Constant part, varying part and RMSE of the inclination error, degrees."""
    d = np.degrees(np.cross(up_in_sensor(quat[used]), up_in_sensor(rec["truth"][used])))
    rms = float(np.sqrt((d ** 2).sum(axis=1).mean()))
    constant = float(np.linalg.norm(d.mean(axis=0)))
    return constant, float(np.sqrt(max(rms ** 2 - constant ** 2, 0.0))), rms


def truth_earlier(truth, shift):
    """The truth `shift` samples earlier (N, 4): `truth[k - shift]`, a fractional shift by the
    normalised linear interpolation of the two neighbours (sign-aligned); NaN (not counted by
    the metrics) where that would precede the recording."""
    whole = int(np.floor(shift))
    frac = shift - whole

    def back(n):
        out = np.full_like(truth, np.nan)
        out[n:] = truth[: len(truth) - n]
        return out

    a, b = back(whole), back(whole + 1)
    b = b * np.sign(np.sum(a * b, axis=1, keepdims=True))
    q = (1.0 - frac) * a + frac * b
    return q / np.linalg.norm(q, axis=1, keepdims=True)


TIME_SHIFTS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5)


def time_offset_table(recs, est_by_trial, commit):
    """Mean inclination RMSE of the flagship and VQF, online and offline, against the truth
    shifted earlier by each of `TIME_SHIFTS` samples (a markdown table)."""
    names = ("flagship", "VQF online", "flagship offline", "VQF offline")
    sums = {(n, s): [] for n in names for s in TIME_SHIFTS}
    for rec, est in zip(recs, est_by_trial):
        for s in TIME_SHIFTS:
            shifted = dict(rec, truth=truth_earlier(rec["truth"], s))
            for n in names:
                sums[n, s].append(rf.rmse(est[n], shifted, dof=6)["inclination"])
    dt_ms = 1e3 * float(np.median(np.diff(recs[0]["t"])))
    lines = [
        f"Mean inclination RMSE over the trials, degrees (6D), against the optical truth "
        f"taken earlier. {platform.node()}, commit {commit}, `benches/python/inclination_parts.py`, "
        f"vqf {VQF_VERSION}.",
        "",
        "| truth taken earlier by | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for s in TIME_SHIFTS:
        cells = " | ".join(f"{np.mean(sums[n, s]):.3f}" for n in names)
        lines.append(f"| {s:g} samples ({s * dt_ms:.2f} ms) | {cells} |")
    return "\n".join(lines)


def estimates(rec):
    t = rec["t"]
    dt = float(np.median(np.diff(t)))
    gyr, acc = np.ascontiguousarray(rec["gyr"]), np.ascontiguousarray(rec["acc"])
    return {
        "flagship": rf.Filter("flagship", dof=6).update_batch(gyr, acc, None, t=t)["quat"],
        "one window": rf.Filter("flagship", dof=6, tau_acc_long=0).update_batch(gyr, acc, None, t=t)["quat"],
        "VQF online": vqf.VQF(dt).updateBatch(gyr, acc)["quat6D"],
    }


def offline_estimates(rec):
    """The flagship smoothed and VQF offline, 6D (quaternions (N, 4))."""
    t = rec["t"]
    gyr, acc = np.ascontiguousarray(rec["gyr"]), np.ascontiguousarray(rec["acc"])
    return {
        "flagship offline": rf.smooth("flagship", gyr, acc, None, t=t, dof=6)["quat"],
        "VQF offline": vqf.offlineVQF(gyr, acc, None, float(np.median(np.diff(t))))["quat6D"],
    }


def main(argv=None):
    a = broad_parser(__doc__).parse_args(argv)
    files = broad_trials(a.broad)
    rows, sums, recs, ests = [], {}, [], []
    for f in files:
        rec = rf.read_csv(f)
        est = estimates(rec)
        recs.append(rec)
        ests.append(dict(est, **offline_estimates(rec)))
        used = rf.error_series(est["flagship"], rec, dof=6)["used"]
        cells = {name: parts(q, rec, used) for name, q in est.items()}
        for name, c in cells.items():
            sums.setdefault(name, []).append(c)
        rows.append((f.name[:2], cells))
        print(f"{f.name[:2]} done", file=sys.stderr)
    names = list(sums)
    commit = docs_page.commit()
    lines = [
        f"Inclination error, degrees, constant / varying / RMSE (6D, online). {platform.node()}, "
        f"commit {commit}, `benches/python/inclination_parts.py`, vqf {VQF_VERSION}.",
        "",
        "| trial | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    fmt = lambda c: f"{c[0]:.2f} / {c[1]:.2f} / {c[2]:.3f}"
    for trial, cells in rows:
        lines.append(f"| {trial} | " + " | ".join(fmt(cells[n]) for n in names) + " |")
    means = {n: tuple(np.mean(sums[n], axis=0)) for n in names}
    lines.append("| **mean** | " + " | ".join(fmt(means[n]) for n in names) + " |")
    docs_page.publish(a.docs, {"inclination_parts": "\n".join(lines),
                               "inclination_time_offset": time_offset_table(recs, ests, commit)})


if __name__ == "__main__":
    main()
