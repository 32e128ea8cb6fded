"""Instructions per channel-update of `run_many`, counted by callgrind: a repeatable second
figure beside `fleet_doors.py`'s times (docs/performance.md, "The engine behind every door").

    .venv/bin/python benches/python/door_instructions.py [--channels 256] [--samples 2000] [--docs]

Needs `valgrind` and the extension built (`maturin develop --release` in crates/rootfuse-py).
Each case runs in a child process under `valgrind --tool=callgrind`, once with one call of
`run_many` and once with three, on one thread (`RAYON_NUM_THREADS=1`, `PYTHONHASHSEED=0`);
the difference of the two totals over the channel-updates of two calls is the figure (the
setup cancels). Data: the
first samples of BROAD trial 07, the same stretch in every channel (the folder
`../shared/broad_csv` or `$ROOTFUSE_BROAD_DIR`), or a simulated recording without it.
Counts inside `memcpy` are inflated under valgrind (`rep movsb` counts a byte at a time).
`--docs [PAGE]` writes the table between `<!-- door_instructions:begin -->` and
`<!-- door_instructions:end -->` in PAGE (docs/performance.md).
"""

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(__file__))
import docs_page  # noqa: E402

CASES = {
    "mahony 6D, float32 in, one dt": ("mahony", 6, "float32", "dt"),
    "mahony 6D, float32 in, t= (C, N)": ("mahony", 6, "float32", "t"),
    "mahony 6D, float64 in, one dt": ("mahony", 6, "float64", "dt"),
    "flagship 9D, float32 in, t= (C, N)": ("flagship", 9, "float32", "t"),
    "flagship 9D, float64 in, t= (C, N)": ("flagship", 9, "float64", "t"),
}


def child(filt, dof, dtype, steps, channels, samples, calls):
    import numpy as np
    import rootfuse as rf

    folder = os.environ.get("ROOTFUSE_BROAD_DIR", os.path.join(os.path.dirname(__file__), "../../../shared/broad_csv"))
    path = os.path.join(folder, "07_undisturbed_fast_rotation_B.csv")
    rec = rf.read_csv(path) if os.path.exists(path) else rf.simulate("fast-rotation", duration_s=samples / 100 + 1)
    n = min(samples, len(rec["t"]))
    stack = lambda x: np.ascontiguousarray(np.broadcast_to(x[:n], (channels,) + x[:n].shape)).astype(dtype)  # noqa: E731
    gyr, acc = stack(rec["gyr"]), stack(rec["acc"])
    mag = stack(rec["mag"]) if dof == 9 else None
    t = np.ascontiguousarray(np.broadcast_to(rec["t"][:n], (channels, n)))
    step = float(np.median(np.diff(rec["t"][:n])))
    for _ in range(calls):
        if steps == "t":
            rf.run_many(filt, gyr, acc, mag, t=t, dof=dof, precision="f32", series=False)
        else:
            rf.run_many(filt, gyr, acc, mag, step, dof=dof, precision="f32", series=False)
    print(n)


def count(case, args, calls):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", sys.executable, __file__,
               "--child", case, "--channels", str(args.channels), "--samples", str(args.samples),
               "--calls", str(calls)]
        # One thread, and the interpreter's hashing fixed so that its own work repeats.
        env = dict(os.environ, RAYON_NUM_THREADS="1", PYTHONHASHSEED="0")
        run = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
        total = int(re.search(r"Collected : (\d+)", run.stderr).group(1))
        return total, int(run.stdout.split()[-1])


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--channels", type=int, default=256)
    p.add_argument("--samples", type=int, default=2000)
    p.add_argument("--docs", nargs="?", const="docs/performance.md", default=None)
    p.add_argument("--child", help=argparse.SUPPRESS)
    p.add_argument("--calls", type=int, default=1, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        child(*CASES[args.child], args.channels, args.samples, args.calls)
        return
    lines = [f"{platform.node()}, commit {docs_page.commit()}, `benches/python/door_instructions.py --channels "
             f"{args.channels} --samples {args.samples}`: `run_many` on one thread, final state, "
             "instructions per channel-update (callgrind).", "",
             "| case | instructions |", "|---|---|"]
    for case in CASES:
        one, n = count(case, args, 1)
        three, _ = count(case, args, 3)
        lines.append(f"| {case} | {(three - one) / (2 * args.channels * n):.1f} |")
        print(lines[-1], flush=True)
    docs_page.publish(args.docs, {"door_instructions": "\n".join(lines)})


if __name__ == "__main__":
    main()
