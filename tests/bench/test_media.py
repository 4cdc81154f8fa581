"""convsss bench media (heterogeneous interiors against path tracing): a tiny run end to end."""

import pytest

from convsss.bench.media import bench_media, media_table


@pytest.mark.slow
def test_a_tiny_run_gives_a_row_with_what_the_default_rendered(tmp_path):
    """The 1.5 mm of skin1 over whole milk, 16², 4-spp references, one render each: a row per scene whose classes
    come from the object's survey (two) and whose render is the default's, which walks there (skin1's blue albedo
    is below 0.95), so it drew no surface samples (the row had read them from a transport and failed when walks
    rendered alone). The table prints it."""
    result = bench_media(("skin-over-milk",), width=16, reference_spp=4, runs=1, folder=tmp_path, progress=False)
    (row,) = result["rows"]
    assert row["classes"] == 2 and row["walk_depth"] == "inf" and row["samples"] == 0
    assert all(value > 0 for value in row["mean_ratio"])
    assert "skin-over-milk" in media_table(result)
