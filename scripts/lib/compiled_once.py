"""Fails when a crate compiled by one build of a test run is compiled again by a later one.

Usage: compiled_once.py FIRST_LOG LATER_LOG...  (cargo's or maturin's output, in build order)

Cargo prints `Compiling <name> v<version>` once per package and build; a package in two of
the logs was compiled twice (usually: a dependency with another feature set in a build of one
package; crates/rootfuse-workspace-hack and .config/hakari.toml say how that is prevented)."""

import re
import sys

LINE = re.compile(r"^\s*Compiling (\S+) v(\S+)")


def compiled(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        text = re.sub(r"\x1b\[[0-9;]*m", "", f.read())
    return {(m.group(1), m.group(2)) for m in map(LINE.match, text.splitlines()) if m}


def main(paths):
    seen = {}
    twice = []
    for path in paths:
        for crate in sorted(compiled(path)):
            if crate in seen:
                twice.append(f"{crate[0]} v{crate[1]} ({seen[crate]}, again in {path})")
            else:
                seen[crate] = path
    if twice:
        print("compiled twice:\n  " + "\n  ".join(twice), file=sys.stderr)
        print("the workspace-hack is stale: cargo hakari generate && cargo hakari manage-deps", file=sys.stderr)
        return 1
    print(f"compiled once: {len(seen)} crates over {len(paths)} builds")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
