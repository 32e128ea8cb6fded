#!/usr/bin/env bash
# Build the Fusion AHRS C cost harness (benches/fusion_c/fusion_loop.c) into
# target/fusion_c/fusion_loop. It measures ns (CPU time, best of passes) per
# FusionAhrsUpdate (9d) / FusionAhrsUpdateNoMagnetometer (6d), default settings
# as in the imufusion package, for comparison with our Mahony/Madgwick filters.
#
#   benches/fusion_c/build.sh                      # fetches the imufusion sdist via pip
#   FUSION_SRC=/path/to/Fusion benches/fusion_c/build.sh   # dir holding FusionAhrs.c, Fusion.h
#   benches/fusion_c/build.sh /path/to/Fusion      # same, as an argument
#   target/fusion_c/fusion_loop 9d 20000 3 ; target/fusion_c/fusion_loop 6d
#   # instructions/update: callgrind, PASSES 1 vs 2, difference / SAMPLES:
#   valgrind --tool=callgrind --callgrind-out-file=/dev/null target/fusion_c/fusion_loop 9d 20000 1
#
# Fusion's sources are never copied into the repo. Env: CC (gcc), IMUFUSION_VERSION
# (pin the sdist, e.g. 1.3.3), FUSION_FAST_SQRT=1 (Fusion's fast inverse sqrt
# instead of imufusion's FUSION_USE_NORMAL_SQRT).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
src="${1:-${FUSION_SRC:-}}"
tmp=""
cleanup() { if [ -n "$tmp" ]; then rm -rf "$tmp"; fi; }
trap cleanup EXIT

if [ -z "$src" ]; then
    tmp="$(mktemp -d)"
    spec="imufusion${IMUFUSION_VERSION:+==$IMUFUSION_VERSION}"
    # sdist only for imufusion; its build deps (setuptools, numpy) come as wheels
    # for pip's metadata step (--no-binary :all: would compile them, cmake included).
    python3 -m pip download "$spec" --no-binary imufusion --no-deps -q -d "$tmp" >&2
    tar -xzf "$tmp"/imufusion-*.tar.gz -C "$tmp"
    src="$(dirname "$(find "$tmp" -path '*/Fusion/FusionAhrs.c' | head -n 1)")"
fi
[ -f "$src/FusionAhrs.c" ] && [ -f "$src/Fusion.h" ] || { echo "no FusionAhrs.c/Fusion.h in '$src'" >&2; exit 1; }

defs=(-DFUSION_USE_NORMAL_SQRT)
[ "${FUSION_FAST_SQRT:-0}" = 1 ] && defs=()

out="$root/target/fusion_c"
mkdir -p "$out"
"${CC:-gcc}" -O3 -march=x86-64-v3 -ffp-contract=fast "${defs[@]}" -I"$src" \
    -o "$out/fusion_loop" "$root/benches/fusion_c/fusion_loop.c" "$src/FusionAhrs.c" -lm
echo "built $out/fusion_loop (Fusion from $src)" >&2
