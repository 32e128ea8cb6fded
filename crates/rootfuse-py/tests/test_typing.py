"""The type stubs are exact: `python -m mypy.stubtest rootfuse` finds no difference between
`rootfuse/_rootfuse.pyi` (and the Python modules) and the built extension, and the README's
Python example type-checks with mypy as written. Skipped only where mypy is not installed
(scripts/test-all.sh installs it)."""

import pathlib
import re
import subprocess
import sys

import pytest

pytest.importorskip("mypy", reason="mypy not installed: the stubs are not checked")

ROOT = pathlib.Path(__file__).resolve().parents[3]
# The READMEs whose Python blocks test_readme.py runs: the quick start and the package's tour.
READMES = [ROOT / "README.md", ROOT / "crates" / "rootfuse-py" / "README.md"]
# Entries for what stubtest reports and the stubs cannot express, each with a comment why;
# none are needed today (the file may be absent).
ALLOWLIST = pathlib.Path(__file__).with_name("stubtest_allowlist.txt")


def _mypy(args, cwd):
    """Runs `python -m <args>` in `cwd` (a fresh folder: no cache or config of the checkout)."""
    return subprocess.run(
        [sys.executable, "-m", *args], cwd=cwd, capture_output=True, text=True, timeout=900
    )


def test_stubtest_finds_no_difference(tmp_path):
    args = ["mypy.stubtest", "rootfuse", "--concise"]
    if ALLOWLIST.exists():
        args += ["--allowlist", str(ALLOWLIST)]
    r = _mypy(args, tmp_path)
    assert r.returncode == 0, f"stubtest:\n{r.stdout}{r.stderr}"


@pytest.mark.parametrize("readme", READMES, ids=lambda p: str(p.relative_to(ROOT)))
def test_readme_python_examples_type_check(readme, tmp_path):
    # Every ```python block, as test_readme.py runs it.
    blocks = re.findall(r"```python\n(.*?)```", readme.read_text(), re.S)
    assert blocks, f"{readme} has no ```python block"
    example = tmp_path / "readme_example.py"
    example.write_text("\n".join(blocks))
    r = _mypy(["mypy", "--no-incremental", "--show-error-codes", str(example)], tmp_path)
    assert r.returncode == 0, f"mypy on {readme.name}'s examples:\n{r.stdout}{r.stderr}"


def test_run_many_types_follow_series_and_dtype(tmp_path):
    # `series` as a runtime bool picks the last overload (no overload matched it before).
    example = tmp_path / "run_many_types.py"
    example.write_text(
        "import numpy as np\n"
        "import rootfuse as rf\n"
        "g = np.zeros((2, 10, 3)); a = np.zeros((2, 10, 3)); a[..., 2] = 9.81\n"
        "def run(keep_series: bool) -> object:\n"
        "    return rf.run_many('mahony', g, a, dt=0.01, series=keep_series)\n"
        "r = rf.run_many('mahony', g, a, dt=0.01, dtype='float32')\n"
        "print(r['quat'].shape, r['rejections'][0])\n"
    )
    r = _mypy(["mypy", "--no-incremental", "--show-error-codes", str(example)], tmp_path)
    assert r.returncode == 0, f"mypy:\n{r.stdout}{r.stderr}"
