"""Accuracy of the flagship beside VQF (the `vqf` package, its C++ core), online and offline,
on the simulated hard cases for inclination and on the shared BROAD trials: mean RMSE in
degrees, total / inclination, one table per data set, rows in one run.

    .venv/bin/python benches/python/accuracy_peers.py [--seeds 5] [--seconds 120] [--broad DIR]
                                                      [--docs docs/accuracy.md]

Scenarios (`rootfuse simulate --scenario NAME`): `pendulum`, `vehicle`, `handheld-translation`
run as 6D (their `-6d` variants, no magnetometer) and as 9D with a disturbed field (their
`-disturbed` variants), seeds 0..N-1, 100 Hz. Every filter sees the same samples; the 6D
scores remove each estimate's constant heading offset (the BROAD 6D metric). With `--docs`
the tables replace the text between `<!-- accuracy_peers:begin -->` and
`<!-- accuracy_peers:end -->` in that file.
"""

import argparse
import pathlib
import platform
import sys

import numpy as np

import docs_page
import rootfuse as rf

try:
    import vqf
except ImportError:  # a bench, not a test: say what is missing and stop
    sys.exit("vqf is not installed: .venv/bin/pip install vqf")

try:
    from importlib.metadata import version

    VQF_VERSION = version("vqf")
except Exception:  # noqa: BLE001 - only for the header line
    VQF_VERSION = "unknown"

SCENARIOS = ("pendulum", "vehicle", "handheld-translation")
REPO = pathlib.Path(__file__).resolve().parents[2]


def flagship(rec, dof, offline):
    mag = rec["mag"] if dof == 9 else None
    if offline:
        return rf.smooth("flagship", rec["gyr"], rec["acc"], mag, t=rec["t"], dof=dof)["quat"]
    f = rf.Filter("flagship", dof=dof)
    return f.update_batch(rec["gyr"], rec["acc"], mag, t=rec["t"])["quat"]


def vqf_run(rec, dof, offline):
    """VQF's quaternions for `rec` (regular sampling: Ts from the median step)."""
    ts = float(np.median(np.diff(rec["t"])))
    gyr = np.ascontiguousarray(rec["gyr"], dtype=np.float64)
    acc = np.ascontiguousarray(rec["acc"], dtype=np.float64)
    mag = np.ascontiguousarray(rec["mag"], dtype=np.float64) if dof == 9 else None
    if offline:
        out = vqf.offlineVQF(gyr, acc, mag, ts)
    else:
        out = vqf.VQF(ts).updateBatch(gyr, acc, mag) if mag is not None else vqf.VQF(ts).updateBatch(gyr, acc)
    return out["quat9D"] if dof == 9 else out["quat6D"]


RUNS = {
    "flagship online": lambda rec, dof: flagship(rec, dof, False),
    "VQF online": lambda rec, dof: vqf_run(rec, dof, False),
    "flagship offline": lambda rec, dof: flagship(rec, dof, True),
    "VQF offline": lambda rec, dof: vqf_run(rec, dof, True),
}


def score(rec, dof):
    """{run: (total, inclination)} of every run on `rec`."""
    out = {}
    for name, run in RUNS.items():
        r = rf.rmse(run(rec, dof), rec["truth"], use=rec.get("use"), dof=dof)
        out[name] = (r["total"], r["inclination"])
    return out


def table(rows, header):
    lines = [f"| {header} | " + " | ".join(RUNS) + " |", "|---|" + "---|" * len(RUNS)]
    for label, scores in rows:
        cells = [f"{scores[k][0]:.2f} / {scores[k][1]:.2f}" for k in RUNS]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def scenario_rows(seeds, seconds):
    rows = []
    for base in SCENARIOS:
        for dof, variant in ((6, f"{base}-6d"), (9, f"{base}-disturbed")):
            per_seed = [
                score(rf.simulate(variant, seed=s, duration_s=seconds, rate_hz=100.0), dof)
                for s in range(seeds)
            ]
            mean = {k: tuple(np.mean([p[k][i] for p in per_seed]) for i in range(2)) for k in RUNS}
            rows.append((f"{variant} {dof}D", mean))
            print(f"{variant} {dof}D done", file=sys.stderr)
    return rows


def broad_parser(description):
    """The arguments of the scripts that score the BROAD trials: `--broad DIR` (the shared trials
    beside the repository by default) and `--docs PAGE` (write the tables into that page)."""
    p = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--broad", default=str(REPO.parent / "shared" / "broad_csv"))
    p.add_argument("--docs", help="write the tables into this file between their markers")
    return p


def broad_trials(folder, stop=True):
    """The BROAD trials of `folder` (files named after their number, `NN_*.csv`), sorted; with
    `stop`, exits naming the folder where there are none."""
    files = sorted(p for p in pathlib.Path(folder).glob("*.csv") if p.name[:2].isdigit())
    if stop and not files:
        sys.exit(f"no BROAD trials in {folder}")
    return files


def broad_rows(folder):
    files = broad_trials(folder, stop=False)
    rows = []
    for dof in (9, 6):
        per_file = []
        for p in files:
            rec = rf.read_csv(p)
            if rec.get("mag") is None and dof == 9:
                continue
            per_file.append(score(rec, dof))
        mean = {k: tuple(np.mean([p[k][i] for p in per_file]) for i in range(2)) for k in RUNS}
        rows.append((f"BROAD, {len(per_file)} trials, {dof}D", mean))
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--seconds", type=float, default=120.0)
    p.add_argument("--broad", default=str(REPO.parent / "shared" / "broad_csv"))
    p.add_argument("--docs", help="write the tables into this file between the markers")
    a = p.parse_args(argv)
    commit = docs_page.commit()
    head = (
        f"Mean RMSE, degrees, total / inclination. {platform.node()}, commit {commit}, "
        f"`benches/python/accuracy_peers.py --seeds {a.seeds} --seconds {a.seconds:g}`, vqf {VQF_VERSION}."
    )
    text = head + "\n\n" + table(scenario_rows(a.seeds, a.seconds), f"scenario ({a.seeds} seeds, {a.seconds:g} s)")
    if pathlib.Path(a.broad).is_dir():
        text += "\n\n" + table(broad_rows(a.broad), "recordings")
    print(text)
    if a.docs:
        docs_page.write_between_markers(a.docs, "accuracy_peers", text)


if __name__ == "__main__":
    main()
