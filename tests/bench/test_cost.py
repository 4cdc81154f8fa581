"""``convsss bench cost``: its rows and table on a tiny run (times are printed, never asserted)."""

import pytest
from click.testing import CliRunner

from convsss.bench.cost import bench_cost, cost_table
from convsss.cli import cli


@pytest.mark.slow
def test_a_tiny_run_times_the_sample_and_the_three_commands():
    result = bench_cost(("milk4",), width=16, spp=2, runs=1, progress=False)
    (row,) = result["rows"]
    assert row["scene"] == "milk4" and set(row["command_s"]) == {"inf", "auto", "mitsuba"}
    assert row["ratio"] == pytest.approx(row["convsss_s"] / row["volpathmis_s"])
    assert row["ratio_no_rr"] == pytest.approx(row["convsss_no_rr_s"] / row["volpathmis_no_rr_s"])
    # the walk at 16² and 2 spp is one chunk: at least its kernel and the film's, each within the render's time
    assert row["kernel_count"] >= 2 and 0 < row["kernels_s"] <= row["convsss_s"]
    assert row["outside_kernels_s"] == pytest.approx(row["convsss_s"] - row["kernels_s"])
    assert "milk4" in cost_table(result).splitlines()[-1]


def test_the_command_explains_itself_and_refuses_an_unknown_scene():
    from convsss.bench.walk import WALK_SCENES
    from convsss.cli.bench import WALK_SCENE_NAMES

    assert WALK_SCENE_NAMES == tuple(WALK_SCENES)  # the names the command line offers are the scenes there are
    runner = CliRunner()
    assert "--no-commands" in runner.invoke(cli, ["bench", "cost", "--help"]).output
    result = runner.invoke(cli, ["bench", "cost", "--scene", "teapot"])
    assert result.exit_code == 2 and "teapot" in result.output
