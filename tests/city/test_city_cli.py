"""``envcap capture CITY`` with city options: bad options are one line, exit 2, before any output."""

import pytest

from envcap.cli import main


@pytest.mark.parametrize("extra, words", [
    (["--workers", "-1"], "--workers must be >= 0, got -1"),
    (["--workers", "0", "--map-cell", "0"], "--map-cell must be a positive number of meters"),
    (["--workers", "0", "--map-cell", "100"], "covers no cell centre at cell 100.0 m"),
    (["--workers", "0", "--shard-mb", "-1"], "--shard-mb must be >= 0"),
    (["--workers", "0", "--retries", "-1"], "--retries must be >= 0"),
])
def test_bad_city_options_fail_before_any_output(tmp_path, capsys, extra, words):
    out = tmp_path / "city"
    assert main(["capture", "crossing", "--out", str(out), "--resolution", "8", *extra]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1
    assert not out.exists()
