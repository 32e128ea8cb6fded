"""Shared fixtures: the `rootfuse` CLI binary (for bit-for-bit comparisons with the Rust
library) and the BROAD folder."""

import os
import pathlib
import shutil

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def _cli():
    env = os.environ.get("ROOTFUSE_BIN")
    if env:
        return env
    for profile in ("release", "debug"):
        p = REPO / "target" / profile / "rootfuse"
        if p.exists():
            return str(p)
    return shutil.which("rootfuse")


@pytest.fixture(scope="session")
def cli():
    """Path of the `rootfuse` binary. scripts/test-all.sh builds it and sets ROOTFUSE_BIN, and
    then a missing binary fails; run alone, the comparison tests are skipped with this note."""
    path = _cli()
    if path is None:
        if os.environ.get("ROOTFUSE_REQUIRE_CLI"):
            pytest.fail("ROOTFUSE_REQUIRE_CLI is set but no rootfuse binary was found")
        pytest.skip("no rootfuse binary (cargo build -p rootfuse-cli, or set ROOTFUSE_BIN): bit-for-bit comparison not run")
    return path


@pytest.fixture(scope="session")
def broad_dir():
    d = pathlib.Path(os.environ.get("ROOTFUSE_BROAD_DIR", REPO.parent / "shared" / "broad_csv"))
    if not d.is_dir():
        if os.environ.get("CI"):
            pytest.fail(f"BROAD folder {d} missing under CI")
        pytest.skip(f"BROAD folder {d} absent: BROAD comparisons not run")
    return d
