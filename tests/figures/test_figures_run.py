"""`convsss figures --quick` end to end, as a user runs it, then again to check that references come from the cache:
every figure, at the smallest panels that keep the figures' distinctions (:data:`RESOLUTION`)."""

import json
import math
import re

import pytest
from click.testing import CliRunner

from convsss.cli import cli
from convsss.figures import FIGURES
from convsss.figures.render import PROFILE_COLUMNS
from convsss.image import read_image

#: Every test here shares the module's render of the figures: all of them are slow.
pytestmark = pytest.mark.slow
#: The panels' side in pixels (``--resolution``; the quick run's own is 128): the exact sums, most of the run's time,
#: cost the visible points times the samples.
RESOLUTION = 48


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("figures")
    result = run("figures", "--quick", "--resolution", RESOLUTION, "--output", out, "--no-progress")
    assert result.exit_code == 0, result.output
    return out, json.loads((out / "figures.json").read_text())


def _finite(summary):
    return summary is not None and all(math.isfinite(summary[k]) for k in ("mre", "ratio", "rel_l2", "flip"))


def test_every_sheet_exr_and_the_report_exist(quick_run):
    out, data = quick_run
    assert [f["key"] for f in data["figures"]] == list(FIGURES)
    for figure in data["figures"]:
        assert (out / figure["sheet"]).is_file() and (out / figure["key"] / f"{figure['key']}.png").is_file()
        assert (out / figure["errors_sheet"]).is_file()
        for panel in figure["panels"]:
            image = read_image(out / panel["exr"])
            assert image.shape == (RESOLUTION, RESOLUTION, 3) and image.max() > 0
            assert (out / panel["png"]).is_file()
    assert (out / "report.md").is_file()
    assert data["cache"]["misses"] > 0


def test_report_has_a_row_with_finite_errors_for_every_panel(quick_run):
    out, data = quick_run
    report = (out / "report.md").read_text()
    for figure in data["figures"]:
        section = report.split(f"## {figure['title']}")[1].split("\n## ")[0]
        table = next(block for block in section.split("\n\n") if block.startswith("| panel"))
        rows = [line for line in table.splitlines() if line.startswith("| ") and not line.startswith("| panel")]
        assert len(rows) == len(figure["panels"]), figure["key"]
        for panel, row in zip(figure["panels"], rows):
            assert row.startswith(f"| {panel['title']} |")
            if panel["method"] in ("convolution", "hierarchical"):
                assert _finite(panel["vs_exact"]), (figure["key"], panel["panel"])
                assert re.search(r"\| \d+\.\d %", row), row
                assert panel["seconds"] > 0 and panel["sss_seconds"] > 0
            if figure["versus_pt"] and panel["method"] != "volpathmis":
                assert _finite(panel["vs_pt"]), (figure["key"], panel["panel"])
            if panel["method"] == "convolution":
                assert 1 <= panel["c"] <= panel["params"].get("layers", 8)
    assert "## Closing note: headline numbers" in report
    assert "## Where this disagrees with the paper, explained" in report


def test_figures_against_path_tracing_report_every_profile_column(quick_run):
    """Each exact-sum column (every model at the paper's setting, and the renderer's own physics) against volpathmis,
    per scene; the dipole's column is the exact panel's (the same sum: the dipole is the default model)."""
    out, data = quick_run
    report = (out / "report.md").read_text()
    for figure in (f for f in data["figures"] if f["versus_pt"]):
        scenes = {p["scene"]["material"] for p in figure["panels"]}
        assert len(figure["profiles"]) == len(scenes)
        for row in figure["profiles"]:
            assert list(row["columns"]) == list(PROFILE_COLUMNS)
            assert all(_finite(summary) for summary in row["columns"].values()), (figure["key"], row["scene"])
            assert f"| {row['scene']} |" in report
        exact = next(p for p in figure["panels"] if p["method"] == "exact")
        if len(scenes) == 1:
            assert figure["profiles"][0]["columns"]["dipole"]["mre"] == pytest.approx(exact["vs_pt"]["mre"])


def test_fig2_counts_fewer_convolutions_for_the_larger_bunny_and_the_larger_threshold(quick_run):
    _, data = quick_run
    c = {p["panel"]: p["c"] for p in data["figures"][0]["panels"]}
    assert c["t0-small"] == c["t0-large"] == 8
    assert c["t0_1-large"] < c["t0_1-small"] and c["t5-large"] <= c["t0_1-large"]
    assert c["t5-small"] < c["t0_1-small"]


def test_second_run_reuses_the_cached_references(quick_run):
    out, _ = quick_run
    result = run("figures", "--quick", "--resolution", RESOLUTION, "--only", "fig5", "--output", out, "--no-progress")
    assert result.exit_code == 0, result.output
    data = json.loads((out / "figures.json").read_text())
    assert data["cache"] == {"hits": 2 + len(PROFILE_COLUMNS), "misses": 0, "root": "cache"}
    panels = {p["panel"]: p for p in data["figures"][0]["panels"]}
    assert panels["exact"]["cached"] and panels["volpathmis"]["cached"]
    assert f"{2 + len(PROFILE_COLUMNS)} reused from `cache/`, 0 rendered" in (out / "report.md").read_text()


@pytest.mark.slow
def test_references_rendered_on_a_cluster_are_what_the_run_reads_from_the_cache(tmp_path):
    """convsss figures --workers: the references on a two-worker Dask cluster first; the run then misses none."""
    import dataclasses

    from convsss.figures import QUICK
    from convsss.figures.run import Runner, prefetch_references, reference_calls

    settings = dataclasses.replace(QUICK, resolution=24, spp=1, error_resolution=24, error_spp=1, pt_spp=4)
    calls = reference_calls(["fig2"])
    assert len(calls) == len(FIGURES["fig2"]().scenes())  # one exact sum per scene, none against path tracing
    assert prefetch_references(["fig2"], settings, tmp_path, workers=2, progress=False) == len(calls)
    runner = Runner(settings, tmp_path, progress=False)
    runner.references(FIGURES["fig2"]())
    assert (runner.cache.hits, runner.cache.misses) == (len(calls), 0)
    assert prefetch_references(["fig2"], settings, tmp_path, workers=1, progress=False) == 0  # all cached
