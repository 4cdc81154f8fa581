"""``convsss bench walk``: its rows and table on a tiny run (times are printed, never asserted)."""

import pytest
from click.testing import CliRunner

from convsss.bench.walk import bench_walk, walk_table
from convsss.cli import cli


@pytest.mark.slow
def test_a_tiny_run_names_what_auto_rendered():
    """The 4 mm milk bunny (about 4 transport mean free paths across its mean chord): auto walks to the end."""
    result = bench_walk(("milk4",), width=16, spp=2, reference_spp=4, depths=(0.0, "auto"), progress=False)
    (scene,) = result["scenes"]
    assert result["meta"]["depths"] == ["0", "auto"]
    assert [(r["walk_depth"], r.get("rendered")) for r in scene["rows"]] == [(0.0, "0"), ("auto", "inf"),
                                                                            ("volpathmis", None)]
    assert all(len(r["ratio"]) == 3 and r["seconds"] > 0 for r in scene["rows"])
    assert "auto=inf" in walk_table(result)


@pytest.mark.parametrize("depths", ["4,deep", "-1", "nan", ""])
def test_bad_depths_are_refused_in_one_line(depths):
    result = CliRunner().invoke(cli, ["bench", "walk", "--depths", depths])
    assert result.exit_code == 2 and "give numbers >= 0, inf or auto" in result.output
