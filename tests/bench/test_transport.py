import json

import pytest
from click.testing import CliRunner

from convsss.bench.transport import STAGES, fft_floor
from convsss.cli import cli


@pytest.mark.slow
def test_bench_transport_quick_json_has_its_keys():
    result = CliRunner().invoke(cli, ["bench", "transport", "--quick", "--runs", "1", "--json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)
    assert len(rows) == 1
    row = rows[0]
    assert {"grid", "layers", "threshold", "stage_median_s", "fft_floor_s", "ratio"} <= set(row)
    assert (row["grid"], row["layers"], row["threshold"]) == (512, 8, 0.001)
    assert set(row["stage_median_s"]) == set(STAGES)
    assert row["fft_floor_s"] > 0 and row["ratio"] > 0


def test_fft_floor_runs_the_requested_transforms():
    assert fft_floor((64, 64), forward=2, inverse=1) > 0
