"""``convsss bench volpath``: the equal-error interpolation, the command's refusals (times are printed, never
asserted)."""

import json

import pytest
from click.testing import CliRunner

from convsss.bench.volpath import equal_error_seconds, seconds_to_reach
from convsss.cli import cli


def test_equal_error_time_follows_monte_carlo_noise():
    """On a ladder whose error falls as 1/time, the interpolation returns the time of the target error, inside the
    ladder and beyond both of its ends (extrapolated with slope -1)."""
    seconds = [1.0, 4.0, 16.0]
    errors = [0.8 / s for s in seconds]
    for target in (0.4, 0.8 / 7.0, 0.01, 2.0):
        assert equal_error_seconds(errors, seconds, target) == pytest.approx(0.8 / target)


def test_the_walks_time_to_an_error_is_read_on_its_ladder_and_never_extrapolated():
    """Inside the ladder, log-log interpolation; a target its first rung beats gives that rung's time as a bound; a
    target below its last rung (a biased render's floor) is not reached."""
    seconds, errors = [1.0, 4.0, 16.0], [0.8, 0.2, 0.1]
    assert seconds_to_reach(errors, seconds, 0.4) == (pytest.approx(2.0), False)
    assert seconds_to_reach(errors, seconds, 0.2) == (pytest.approx(4.0), False)
    assert seconds_to_reach(errors, seconds, 0.9) == (1.0, True)
    assert seconds_to_reach(errors, seconds, 0.05) is None


@pytest.mark.parametrize("ladder", ["16,4", "4", "a,b", "0,4"])
def test_a_bad_ladder_is_one_line_before_any_work(ladder):
    result = CliRunner().invoke(cli, ["bench", "volpath", "--ladder", ladder, "--no-progress"])
    assert result.exit_code == 2 and "--ladder" in result.output and "Traceback" not in result.output


@pytest.mark.slow
def test_a_tiny_run_gives_a_row_per_scene(tmp_path):
    out = tmp_path / "v.json"
    result = CliRunner().invoke(cli, ["bench", "volpath", "--scene", "milk40", "--width", "24", "--reference-spp",
                                      "16", "--ladder", "2,8", "--no-progress", "-o", str(out)])
    assert result.exit_code == 0, result.output
    (row,) = json.loads(out.read_text())["rows"]
    assert row["scene"] == "milk40" and [r["spp"] for r in row["ladder"]] == [2, 8]
    assert row["reference_noise"] > 0 and row["convsss_s"] > 0
    assert "milk40" in result.output


@pytest.mark.slow
def test_a_walk_ladder_reads_each_volpath_rung(tmp_path):
    out = tmp_path / "v.json"
    result = CliRunner().invoke(cli, ["bench", "volpath", "--scene", "milk40", "--width", "16", "--reference-spp",
                                      "8", "--ladder", "1,4", "--walk-depth", "4", "--no-progress", "-o", str(out)])
    assert result.exit_code == 0, result.output
    (row,) = json.loads(out.read_text())["rows"]
    assert [w["spp"] for w in row["walk_ladder"]] == [1, 4] and row["events_at_inf"] > 0
    assert [a["spp"] for a in row["at_volpath"]] == [1, 4]
    assert "at volpathmis's error" in result.output
