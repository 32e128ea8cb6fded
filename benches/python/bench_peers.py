"""Speed of rootfuse from Python, side by side in one process on the same data (ratios, not
timed tests).

    .venv/bin/pip install vqf imufusion ahrs      # the peers: bench only, not test deps
    cargo build --release --example filter_loop -p rootfuse
    cargo build --release -p rootfuse-cli
    .venv/bin/python benches/python/bench_peers.py [--broad FILE.csv] [--repeats 5]

Rows: our flagship `update_batch` vs the same loop from Rust (examples/filter_loop.rs, same
outputs), f32 and f64, 9D and 6D; vs `vqf.VQF.updateBatch`; `smooth` vs `vqf.offlineVQF`;
`imufusion` per-sample loop and
`ahrs` Madgwick/Mahony/EKF; 4096 channels x 2000 samples through `run_many` vs `rootfuse
throughput` lanes on all cores. Every time is the best of `--repeats` runs, per sample
(per channel-update for the many-channel rows). A peer that is not installed is reported as
such.
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np

import rootfuse as rf

REPO = pathlib.Path(__file__).resolve().parents[2]


def best_of(fn, repeats):
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def best_in_turns(fns, repeats):
    """Best time of each function over `repeats` rounds in which they take turns: a ratio of
    two functions timed in blocks one after the other moved by 0.8-1.3 with the host's load."""
    best = [float("inf")] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            best[i] = min(best[i], time.perf_counter() - t0)
    return best


def load(path):
    if path and pathlib.Path(path).exists():
        rec = rf.read_csv(path)
        return rec, pathlib.Path(path).name
    rec = rf.simulate("fast-rotation", seed=1, duration_s=300.0, rate_hz=286.0)
    p = REPO / "target" / "bench_sim.csv"
    rf.write_recording(p, rec["t"], rec["gyr"], rec["acc"], rec["mag"], truth=rec["truth"])
    return rf.read_csv(p), "simulated fast-rotation 300 s"


def rust_loop(path, filt, dof, precision, repeats):
    exe = REPO / "target" / "release" / "examples" / "filter_loop"
    if not exe.exists():
        return None
    out = subprocess.run([str(exe), str(path), filt, str(dof), precision, str(repeats)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)["ns_per_sample"]


def main():
    ap = argparse.ArgumentParser()
    default_broad = REPO.parent / "shared" / "broad_csv" / "02_undisturbed_slow_rotation_B.csv"
    ap.add_argument("--broad", default=str(default_broad))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--channels", type=int, default=4096)
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--label", default="")
    args = ap.parse_args()
    rec, data_name = load(args.broad)
    path = args.broad if pathlib.Path(args.broad).exists() else REPO / "target" / "bench_sim.csv"
    gyr, acc, mag, t = rec["gyr"], rec["acc"], rec["mag"], rec["t"]
    n = len(t)
    ts = float(np.median(np.diff(t)))
    rows = []

    def row(what, ns, ref=None, note=""):
        rows.append((what, ns, ref, note))

    print(f"data: {data_name}, {n} samples, {1 / ts:.0f} Hz; build: {rf.build_info()['compiled']}", file=sys.stderr)

    # 1. Flagship from Python vs the same loop from Rust.
    for dof in (9, 6):
        for precision in ("f32", "f64"):
            f = rf.Filter("flagship", dof=dof, precision=precision)
            m = mag if dof == 9 else None

            def go():
                f.reset()
                f.update_batch(gyr, acc, m, t=t)
            ns = best_of(go, args.repeats) * 1e9 / n
            r = rust_loop(path, "flagship", dof, precision, args.repeats)
            row(f"rootfuse flagship {dof}D {precision} update_batch", ns, r,
                "vs Rust loop" if r else "Rust loop not built")

    # 2. Peers.
    try:
        import vqf
        for dof in (9, 6):
            def go_vqf():
                v = vqf.VQF(ts)
                if dof == 9:
                    v.updateBatch(np.ascontiguousarray(gyr), np.ascontiguousarray(acc), np.ascontiguousarray(mag))
                else:
                    v.updateBatch(np.ascontiguousarray(gyr), np.ascontiguousarray(acc))
            ns_vqf = best_of(go_vqf, args.repeats) * 1e9 / n
            # The flagship against VQF's C++ in this run: from Python (update_batch) and as
            # the Rust loop (when examples/filter_loop is built), f32 and f64.
            ratios = []
            for precision in ("f32", "f64"):
                r = next(r for r in rows if r[0] == f"rootfuse flagship {dof}D {precision} update_batch")
                ratios.append(f"ours {precision} / vqf = {r[1] / ns_vqf:.2f}")
                if r[2]:
                    ratios.append(f"Rust loop {precision} / vqf = {r[2] / ns_vqf:.2f}")
            row(f"vqf.VQF.updateBatch {dof}D (C++)", ns_vqf, None, "; ".join(ratios))
        # The smoother against VQF's offline form (both whole recordings, f64).
        for dof in (9, 6):
            m = mag if dof == 9 else None
            gc, ac, mc = (np.ascontiguousarray(x) for x in (gyr, acc, mag))
            ns_ours, ns_off = (
                s * 1e9 / n
                for s in best_in_turns(
                    [
                        lambda: rf.smooth("flagship", gyr, acc, m, t=t, dof=dof),
                        lambda: vqf.offlineVQF(gc, ac, mc if dof == 9 else None, ts),
                    ],
                    args.repeats,
                )
            )
            row(f"rootfuse smooth flagship {dof}D", ns_ours, None, f"ours / offlineVQF = {ns_ours / ns_off:.2f}")
            row(f"vqf.offlineVQF {dof}D (C++)", ns_off)
    except ImportError:
        row("vqf", float("nan"), None, "not installed")

    small = min(n, 20000)
    g_deg, a_g = np.degrees(gyr[:small]), acc[:small] / 9.81
    for name in ("madgwick", "mahony"):
        f = rf.Filter(name, dof=9, precision="f32")

        def go_batch():
            f.reset()
            f.update_batch(gyr[:small], acc[:small], mag[:small], t=t[:small])
        row(f"rootfuse {name} 9D f32 update_batch", best_of(go_batch, args.repeats) * 1e9 / small)
        gl, al, ml = gyr[:small].tolist(), acc[:small].tolist(), mag[:small].tolist()

        def go_loop():
            f.reset()
            for i in range(small):
                f.update(gl[i], al[i], ml[i], dt=ts)
        row(f"rootfuse {name} 9D f32 per-sample update() loop", best_of(go_loop, 2) * 1e9 / small)
    try:
        import imufusion
        ml = mag[:small]

        def go_fusion():
            ahrs = imufusion.Ahrs()
            ahrs.set_sample_period(ts)  # imufusion 1.3: the period is set once
            for i in range(small):
                ahrs.update(g_deg[i], a_g[i], ml[i])
        row("imufusion Ahrs 9D per-sample loop (C)", best_of(go_fusion, 2) * 1e9 / small)
    except ImportError:
        row("imufusion", float("nan"), None, "not installed")
    try:
        import ahrs as ahrs_pkg
        k = min(n, 3000)
        for cls in ("Madgwick", "Mahony", "EKF"):
            C = getattr(ahrs_pkg.filters, cls)

            def go_ahrs():
                C(gyr=gyr[:k], acc=acc[:k], mag=mag[:k], frequency=1 / ts)
            row(f"ahrs {cls} 9D (Python)", best_of(go_ahrs, 1) * 1e9 / k, None, f"{k} samples")
    except ImportError:
        row("ahrs", float("nan"), None, "not installed")

    # 3. Many channels.
    C, N = args.channels, args.samples
    base = min(n, N)
    idx = (np.arange(C)[:, None] * 37 + np.arange(N)[None, :]) % base
    g3 = np.ascontiguousarray(gyr[idx]); a3 = np.ascontiguousarray(acc[idx])
    for series in (False, True):
        def go_many():
            rf.run_many("mahony", g3, a3, None, ts, dof=6, precision="f32", series=series,
                        bias=False, flags=False)
        secs = best_of(go_many, 3 if not series else 2)
        row(f"rootfuse run_many mahony 6D f32 {C}x{N}, {'series' if series else 'final state'}",
            secs * 1e9 / (C * N))
    cli = REPO / "target" / "release" / "rootfuse"
    if cli.exists():
        out = subprocess.run([str(cli), "throughput", "--filter", "mahony", "--dof", "6", "--channels", str(C),
                              "--samples", str(N), "--json"], check=True, capture_output=True, text=True).stdout
        rep = json.loads(out[out.index("{"):])
        lanes = next(r for r in rep["results"] if r["mode"] == "lanes-f32x8-threads")
        row("rootfuse throughput lanes-f32x8-threads (Rust)", lanes["ns_per_update"])

    print(f"\n{args.label} data: {data_name}; best of {args.repeats}\n")
    print("| what | ns per sample | Rust loop (ns) | ratio | note |")
    print("|---|---|---|---|---|")
    ref_many = next((r[1] for r in rows if r[0].startswith("rootfuse throughput")), None)
    for what, ns, ref, note in rows:
        ratio = ""
        if ref:
            ratio = f"{ns / ref:.3f}"
        elif ref_many and what.startswith("rootfuse run_many"):
            ratio = f"{ref_many / ns:.2f} of Rust"
        print(f"| {what} | {ns:.1f} | {'' if ref is None else f'{ref:.1f}'} | {ratio} | {note} |")


if __name__ == "__main__":
    main()
