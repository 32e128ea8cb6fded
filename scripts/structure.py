#!/usr/bin/env python3
"""The house rules that keep the source readable, checked (CI runs this):

- no source file over 800 lines (`crates/*/src`, `src`);
- no function over 120 lines outside tests (`mod tests` blocks and test folders excluded);
- no import circle between the modules of a crate (`use crate::a::…` or `crate::a::…` in
  module `b` is an arrow b -> a; a circle is a strongly connected set of two or more modules).

Prints every breach, one per line with file and line, and exits 1 if there is one.
Usage: scripts/structure.py [ROOT]
"""

import re
import sys
from pathlib import Path

MAX_FILE_LINES = 800
MAX_FUNCTION_LINES = 120

FN = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+\"C\"\s+)?fn\s+(\w+)")
STRING = re.compile(r'"(\\.|[^"\\])*"')
CHAR = re.compile(r"'(\\.|[^'\\])'")
COMMENT = re.compile(r"//.*")


def code(line):
    """The line without strings, character literals and comments (for brace counting)."""
    return COMMENT.sub("", CHAR.sub("''", STRING.sub('""', line)))


def long_functions(path, lines):
    """(line, name, length) of every function over the limit, up to a `mod tests` block."""
    found = []
    i = 0
    while i < len(lines):
        if re.match(r"\s*mod tests\b", lines[i]):
            break
        m = FN.match(lines[i])
        if not m:
            i += 1
            continue
        depth, started, j = 0, False, i
        while j < len(lines):
            text = code(lines[j])
            for ch in text:
                if ch == "{":
                    depth += 1
                    started = True
                elif ch == "}":
                    depth -= 1
            if started and depth == 0:
                break
            if not started and text.rstrip().endswith(";"):
                break
            j += 1
        if started and j - i + 1 > MAX_FUNCTION_LINES:
            found.append((i + 1, m.group(7), j - i + 1))
        i = j + 1 if started else i + 1
    return found


def module_of(src, path):
    """Module path of a file below a crate's `src` (`lib.rs`/`main.rs` is the root)."""
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] in ("lib", "main", "mod"):
        parts = parts[:-1]
    return tuple(parts)


def circles(src, files):
    """The import circles between the modules of one crate, each a sorted list of modules."""
    modules = {module_of(src, f): f for f in files}
    arrows = {m: set() for m in modules}
    for m, f in modules.items():
        text = "\n".join(code(l) for l in f.read_text(encoding="utf-8").splitlines())
        for ref in re.findall(r"crate::((?:\w+::)*\w+)", text):
            target = tuple(ref.split("::"))
            # The longest prefix that is a module of the crate.
            while target and target not in modules:
                target = target[:-1]
            # An arrow to the crate root or to an ancestor is the module tree, not a use.
            if target and target != m and m[: len(target)] != target:
                arrows[m].add(target)
    # Tarjan's strongly connected components.
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in arrows[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in modules:
        if v not in index:
            visit(v)
    return [[str(modules[m]) for m in comp] for comp in out]


def main():
    root = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    srcs = sorted(root.glob("crates/*/src")) + [root / "src"]
    breaches = []
    for src in srcs:
        files = sorted(src.rglob("*.rs"))
        for f in files:
            lines = f.read_text(encoding="utf-8").splitlines()
            if len(lines) > MAX_FILE_LINES:
                breaches.append(f"{f}: {len(lines)} lines (at most {MAX_FILE_LINES}): split it by concern")
            for line, name, n in long_functions(f, lines):
                breaches.append(
                    f"{f}:{line}: fn {name} has {n} lines (at most {MAX_FUNCTION_LINES}): cut it into named steps"
                )
        for comp in circles(src, files):
            breaches.append(f"import circle: {' <-> '.join(comp)}: move what they share where it belongs")
    for b in breaches:
        print(b)
    print(f"structure: {len(breaches)} breach(es) in {len(srcs)} source folders")
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main())
