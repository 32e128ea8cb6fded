"""What the benches share to put their tables into the docs: the commit they measured, and
the page's text between a bench's markers (`<!-- NAME:begin -->` … `<!-- NAME:end -->`)
replaced by the new table."""

import pathlib
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]


def commit():
    """The short hash of the checkout's HEAD (the code a table measured)."""
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                          text=True).stdout.strip()


def write_between_markers(path, name, text):
    """Replaces what stands between the `name` markers of the page `path` (relative to the
    repository, or absolute) with `text`; exits naming the page if it has no such markers."""
    page = REPO / path
    s = page.read_text()
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    if begin not in s or end not in s:
        sys.exit(f"{path} has no {name} markers")
    head, rest = s.split(begin, 1)
    _, tail = rest.split(end, 1)
    page.write_text(f"{head}{begin}\n{text}\n{end}{tail}")


def publish(path, tables):
    """Prints each table of `tables` (marker name → markdown text, in order) and, where `path`
    is given, writes each between its markers in that page."""
    for text in tables.values():
        print(text)
    if path:
        for name, text in tables.items():
            write_between_markers(path, name, text)
