"""``python -m convsss.bench.efficiency``: its rows on a tiny run (times are printed, never asserted)."""

import pytest

from convsss.bench.efficiency import bench_efficiency, efficiency_table, main


@pytest.mark.slow
def test_a_tiny_run_weighs_both_estimators_against_the_references():
    (row,) = bench_efficiency(("milk4",), width=12, spp=2, seeds=2, reference_spp=64, walk_depth=float("inf"))
    assert row["scene"] == "milk4" and row["walk_depth"] == "inf" and row["reference_noise"] > 0
    for label in ("convsss", "volpathmis"):
        r = row[label]
        assert r["seconds"] > 0 and len(r["mean_ratio"]) == 3
        if r["error"] > 0:
            assert r["efficiency"] == pytest.approx(1.0 / (r["seconds"] * r["error"]))
    if row["ratio"] is not None:
        assert row["ratio"] == pytest.approx(row["convsss"]["efficiency"] / row["volpathmis"]["efficiency"])
    assert "milk4" in efficiency_table([row])


def test_an_unknown_scene_is_one_line_and_exit_code_2(capsys, tmp_path):
    out = tmp_path / "rows.json"
    with pytest.raises(SystemExit) as stop:
        main(["teapot", "-o", str(out)])
    assert stop.value.code == 2 and "teapot" in capsys.readouterr().err and not out.exists()
    with pytest.raises(SystemExit) as stop:
        main(["milk4", "--seeds", "0"])
    assert stop.value.code == 2
    for depth in ("deep", "-1"):
        with pytest.raises(SystemExit) as stop:
            main(["milk4", "--walk-depth", depth])
        assert stop.value.code == 2 and depth in capsys.readouterr().err
