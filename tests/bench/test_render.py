"""``convsss bench render``: the rows and the table (times are printed, never asserted)."""

import json

import pytest
from click.testing import CliRunner

from convsss.bench.render import STAGES, bench_render, render_table
from convsss.cli import cli


@pytest.mark.slow
def test_rows_have_every_stage_and_both_integrators():
    rows = bench_render(resolutions=(48,), spps=(2,), runs=1, progress=False)
    assert len(rows) == 1
    row = rows[0]
    assert (row["width"], row["spp"]) == (48, 2)
    assert set(row["stages_s"]) == set(STAGES)
    for name in ("samples", "transport", "shading"):
        assert row["stages_s"][name] > 0
    assert row["convsss_s"] > row["stages_s"]["shading"] > 0 and row["path_s"] > 0
    assert row["shading_ratio"] == row["stages_s"]["shading"] / row["path_s"]
    assert row["screen_queries"] > 0
    table = render_table(rows, {"convsss --version": 0.5})
    assert "48²" in table and "convsss --version: 0.50 s" in table


@pytest.mark.slow
def test_cli_quick_json_without_command_lines():
    result = CliRunner().invoke(cli, ["bench", "render", "--quick", "--runs", "1", "--json", "--no-progress"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["commands"] == {}
    assert [(r["width"], r["spp"]) for r in data["rows"]] == [(256, 1), (256, 4)]


@pytest.mark.slow
def test_scaling_rows_follow_their_commands():
    """Two tiny configurations in fresh processes: a row per configuration, the samples and pixels of its stats."""
    from convsss.bench.render import bench_scaling, scaling_configs, scaling_table

    configs = scaling_configs(widths=(32,), spans=(10,), spp=1)
    assert [(axis, value) for axis, value, _ in configs] == [("width", 32), ("mean free paths", 10)]
    rows = bench_scaling(widths=(32,), spans=(10,), runs=1, spp=1, progress=False)
    assert [r["pixels"] for r in rows] == [32 * 32, 256 * 256]
    assert all(r["seconds"] > r["stages_s"]["shading"] > 0 and r["peak_bytes"] > 2**20 and r["samples"] > 0
               for r in rows)
    assert "mean free paths" in scaling_table(rows)
