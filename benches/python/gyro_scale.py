"""What the gyroscope's scale factor costs on the shared BROAD trials: the 6D heading drift of
each trial against its net rotation about earth-up, and the mean errors of the flagship and
VQF online with the gyroscope's readings multiplied by a few factors.

    .venv/bin/python benches/python/gyro_scale.py [--broad DIR] [--docs docs/accuracy.md]

A gyroscope whose scale factor is off by a fraction `s` turns the estimate `s` times every
angle it measures. Nothing corrects a 6D heading, so its drift over a trial is `s` times the
net rotation about earth-up (the sensor turning the same way again and again adds up; back and
forth cancels), where a bias would drift it with time instead. The first table gives, per trial,
the net rotation about earth-up of the optical truth (the sum of the vertical components of its
rotation between samples), the drift of the flagship's 6D heading error over the trial (the
slope of a line fitted to the signed error, times the duration) and their ratio. The second
scores both filters with the gyroscope's readings multiplied per axis: a factor that helps
both alike is the recording's sensor, not a filter. The flagship runs without its own
estimate of the scale (`gyr_scale_window = 0`), so that the factor is the only one applied.
`--cv` adds the leave-one-trial-out choice of the flagship's own estimate's parameters
(`gyr_scale_ridge` × `gyr_scale_axis_ridge` × `gyr_scale_gate`, 27 sets, the window at its
default; each fold picks the set
with the least `9D/2.10 + 6D/2.35 + inclination/0.70` on the other trials, the issue's targets),
over every set, over the sets with the default gate, and over those with the default gate and
ridge, between
`<!-- gyro_scale_cv:begin -->` / `<!-- gyro_scale_cv:end -->` (about 2 CPU-minutes).
With `--docs` the tables replace the text
between `<!-- gyro_scale_drift:begin -->` / `<!-- gyro_scale_drift:end -->` and
`<!-- gyro_scale:begin -->` / `<!-- gyro_scale:end -->` in that file.
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


# The flagship without its online scale estimate: the factors below are the only ones applied.
FLAGSHIP = {"gyr_scale_window": 0.0}

# Gyroscope factors per axis (x, y, z) scored in the second table.
FACTORS = ((1.0, 1.0, 1.0), (1.002, 1.002, 1.002), (1.0, 1.0, 1.002), (1.0, 1.002, 1.004),
           (1.004, 1.004, 1.004))


def qmul(a, b):
    """Hamilton products of quaternion arrays `[w, x, y, z]` (N, 4)."""
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=1)


def conj(q):
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def net_vertical_rotation(truth):
    """Sum over the samples of the truth's rotation about earth-up between neighbours, degrees
    (steps with an unknown truth left out)."""
    step = qmul(truth[1:], conj(truth[:-1]))  # earth-frame rotation from one sample to the next
    step = step * np.sign(step[:, :1])
    angle_z = 2.0 * np.arctan2(step[:, 3], step[:, 0])  # about earth-up, for small steps
    return float(np.degrees(np.nansum(angle_z)))


def heading_drift(quat, rec):
    """Drift of the signed 6D heading error over the trial, degrees: a line's slope fitted to
    the error about earth-up (truth against estimate) on the samples the metric counts, times
    the counted time span."""
    used = rf.error_series(quat, rec, dof=6)["used"]
    err = qmul(rec["truth"][used], conj(quat[used]))
    yaw = np.unwrap(2.0 * np.arctan2(err[:, 3], err[:, 0]))
    t = rec["t"][used]
    slope = np.polyfit(t - t[0], np.degrees(yaw), 1)[0]
    return float(slope * (t[-1] - t[0]))


def errors(rec, factors):
    """Mean-able errors (9D total, 6D total, 6D inclination) of the flagship and VQF online with
    the gyroscope multiplied by `factors`."""
    gyr = np.ascontiguousarray(rec["gyr"] * np.asarray(factors))
    acc, mag, t = np.ascontiguousarray(rec["acc"]), np.ascontiguousarray(rec["mag"]), rec["t"]
    dt = float(np.median(np.diff(t)))
    out = {}
    q9 = rf.Filter("flagship", dof=9, **FLAGSHIP).update_batch(gyr, acc, mag, t=t)["quat"]
    q6 = rf.Filter("flagship", dof=6, **FLAGSHIP).update_batch(gyr, acc, None, t=t)["quat"]
    v9 = vqf.VQF(dt).updateBatch(gyr, acc, mag)["quat9D"]
    v6 = vqf.VQF(dt).updateBatch(gyr, acc)["quat6D"]
    for name, a, b in (("flagship", q9, q6), ("VQF online", v9, v6)):
        e6 = rf.rmse(b, rec, dof=6)
        out[name] = (rf.rmse(a, rec, dof=9)["total"], e6["total"], e6["inclination"])
    return out


# The parameter grid of the cross-validation (`--cv`), and the objective: the targets.
CV_GRID = [dict(gyr_scale_ridge=r, gyr_scale_axis_ridge=a, gyr_scale_gate=g)
           for r in (0.1, 0.3, 1.0) for a in (1.0, 10.0, 30.0) for g in (0.05, 0.1, 0.2)]
TARGETS = np.array([2.10, 2.35, 0.70])


def flagship_scores(rec, params):
    """The flagship's 9D total, 6D total and 6D inclination RMSE on `rec` with `params`."""
    out = []
    for dof, mag in ((9, rec["mag"]), (6, None)):
        q = rf.Filter("flagship", dof=dof, **params).update_batch(rec["gyr"], rec["acc"], mag, t=rec["t"])["quat"]
        e = rf.rmse(q, rec, dof=dof)
        out += [e["total"]] if dof == 9 else [e["total"], e["inclination"]]
    return out


def cross_validation(recs, source):
    """Leave-one-trial-out over `CV_GRID` (a markdown table): over every set, over the sets with
    the default gate, and over those with the default gate and ridge (the two the simulator
    sets, docs/accuracy.md)."""
    scores = np.array([[flagship_scores(rec, p) for rec in recs] for p in CV_GRID])
    print("cross-validation scored", file=sys.stderr)
    defaults = rf.Filter("flagship").params
    gate, ridge = defaults["gyr_scale_gate"], defaults["gyr_scale_ridge"]
    lines = [f"Leave one trial out over {len(CV_GRID)} sets of `gyr_scale_ridge` (rad²) / "
             f"`gyr_scale_axis_ridge` (rad²) / `gyr_scale_gate` (rad), mean RMSE in degrees, 9D total / 6D total / 6D "
             f"inclination. {source}", "",
             "| sets | in sample, range over the sets | picked (folds) | held out |", "|---|---|---|---|"]
    for label, sets in (("every set", range(len(CV_GRID))),
                        (f"gate {gate:g}", [i for i, p in enumerate(CV_GRID) if p["gyr_scale_gate"] == gate]),
                        (f"gate {gate:g}, ridge {ridge:g}",
                         [i for i, p in enumerate(CV_GRID)
                          if p["gyr_scale_gate"] == gate and p["gyr_scale_ridge"] == ridge])):
        sets = list(sets)
        means = scores[sets].mean(axis=1)
        held, picked = [], {}
        for t in range(len(recs)):
            others = [k for k in range(len(recs)) if k != t]
            best = sets[int(np.argmin((scores[sets][:, others].mean(axis=1) / TARGETS).sum(axis=1)))]
            held.append(scores[best, t])
            picked[best] = picked.get(best, 0) + 1
        ranges = " / ".join(f"{lo:.3f}–{hi:.3f}" for lo, hi in zip(means.min(axis=0), means.max(axis=0)))
        top = max(picked, key=picked.get)
        p = CV_GRID[top]
        choice = f"{p['gyr_scale_ridge']:g} / {p['gyr_scale_axis_ridge']:g} / {p['gyr_scale_gate']:g} ({picked[top]})"
        lines.append(f"| {label} | {ranges} | {choice} | " + " / ".join(f"{x:.3f}" for x in np.mean(held, axis=0)) + " |")
    return "\n".join(lines)


def main(argv=None):
    parser = broad_parser(__doc__)
    parser.add_argument("--cv", action="store_true", help="also cross-validate the estimate's parameters")
    a = parser.parse_args(argv)
    files = broad_trials(a.broad)
    recs = [rf.read_csv(f) for f in files]
    commit = docs_page.commit()
    source = f"{platform.node()}, commit {commit}, `benches/python/gyro_scale.py`, vqf {VQF_VERSION}."

    drift = [f"6D heading drift of the flagship over each trial against the truth's net rotation "
             f"about earth-up, degrees. {source}", "",
             "| trial | net rotation about up | heading drift | drift / rotation |", "|---|---|---|---|"]
    for f, rec in zip(files, recs):
        q6 = rf.Filter("flagship", dof=6, **FLAGSHIP).update_batch(rec["gyr"], rec["acc"], None,
                                                                   t=rec["t"])["quat"]
        turn, d = net_vertical_rotation(rec["truth"]), heading_drift(q6, rec)
        ratio = f"{100.0 * d / turn:+.2f} %" if abs(turn) >= 360.0 else "(under one turn)"
        drift.append(f"| {f.name[:2]} | {turn:+.0f} | {d:+.1f} | {ratio} |")
        print(f"{f.name[:2]} drift done", file=sys.stderr)
    drift = "\n".join(drift)

    names = ("flagship", "VQF online")
    table = [f"Mean RMSE over the 14 trials, degrees, 9D total / 6D total / 6D inclination, online, "
             f"the gyroscope's readings multiplied per axis. {source}", "",
             "| gyroscope × (x, y, z) | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for factors in FACTORS:
        sums = {n: [] for n in names}
        for rec in recs:
            for n, e in errors(rec, factors).items():
                sums[n].append(e)
        cells = " | ".join("{:.3f} / {:.3f} / {:.3f}".format(*np.mean(sums[n], axis=0)) for n in names)
        table.append(f"| {', '.join(f'{x:g}' for x in factors)} | {cells} |")
        print(f"{factors} done", file=sys.stderr)
    tables = {"gyro_scale_drift": drift, "gyro_scale": "\n".join(table)}
    if a.cv:
        tables["gyro_scale_cv"] = cross_validation(recs, source)
    docs_page.publish(a.docs, tables)


if __name__ == "__main__":
    main()
