"""Every file variant of user_files.py through the CLI: the exit code, the message that says
what is wrong and what to do, and for the variants that only change how a file is written, the
same estimate bits as the plain CSV."""

import pathlib
import sys

import numpy as np
import pytest

pytest.importorskip("pandas", reason="pandas not installed: the file variants are written with it")
pytest.importorskip("pyarrow", reason="pyarrow not installed: the Parquet and Arrow variants need it")

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import user_files  # noqa: E402


@pytest.fixture(scope="module")
def df(broad_dir):
    return user_files.recording(broad_dir)


@pytest.fixture(scope="module")
def plain(df, cli, tmp_path_factory):
    return user_files.run(user_files.CASES[0], df, cli, tmp_path_factory.mktemp("plain"))


@pytest.mark.parametrize("case", user_files.CASES, ids=lambda c: c.name)
def test_user_file(case, df, cli, plain, tmp_path):
    got = user_files.run(case, df, cli, tmp_path)
    assert got.exit == case.exit, got.message
    assert case.says in got.message
    if case.exit == 0 and not case.says:
        assert "warning:" not in got.message, got.message
    if case.exit != 0:
        assert got.quat is None, "a failed run writes no estimate"
    if case.same:
        assert got.quat is not None
        if case.name.startswith(("parquet", "arrow", "feather")):
            # Columnar files run through the fleet engine, whose lane arithmetic may round
            # the last bits differently from the scalar CSV path.
            np.testing.assert_allclose(got.quat, plain.quat, rtol=0, atol=1e-12)
        else:
            np.testing.assert_array_equal(got.quat.view(np.uint64), plain.quat.view(np.uint64))


def test_at_least_forty_variants():
    assert len(user_files.CASES) >= 40


def test_read_csv_units_warn_convert_and_strict(df, tmp_path):
    """Python's `read_csv` checks and converts units as `rootfuse run` does."""
    import warnings

    import rootfuse as rf

    path = tmp_path / "deg.csv"
    scaled = df.copy()
    scaled[user_files.GYR] = scaled[user_files.GYR] * user_files.DEG
    scaled["t"] = scaled["t"] * 1e3
    scaled.to_csv(path, index=False)
    # Time in ms is a warning; a gyroscope that fails against the motion an error, as in
    # `rootfuse run`, unless its unit is declared.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(ValueError, match=r'pass units="gyro=deg/s".*pass units="gyro=rad/s"'):
            rf.read_csv(path)
    said = "\n".join(str(w.message) for w in caught)
    assert 'pass units="time=ms"' in said, said
    with pytest.warns(UserWarning, match='pass units="gyro=deg/s"'):
        rf.read_csv(path, units="time=ms,gyro=rad/s")
    with pytest.raises(ValueError, match=r"time=ms.*strict=True"):
        rf.read_csv(path, strict=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rec = rf.read_csv(path, units="time=ms,gyro=deg/s")
    np.testing.assert_allclose(rec["gyr"], df[user_files.GYR].to_numpy(), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(rec["t"], df["t"].to_numpy(), rtol=1e-12)
    with pytest.raises(ValueError, match="units: gyro given twice"):
        rf.read_csv(path, units="gyro=deg/s,gyro=rad/s")
