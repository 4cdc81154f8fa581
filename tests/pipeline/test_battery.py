"""The reliability battery (issue 9) on a tiny scene (:mod:`convsss.bench.battery`): emitter types x boundaries x
transports, and random valid and invalid integrator parameters. Every run ends in a finite, non-negative image or in
one line of ConvsssError. The whole matrix is a benchmark (``convsss bench battery``); here every boundary meets
every transport, the emitters in turn."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import convsss
from convsss.bench.battery import battery_table, bench_battery, matrix, pairwise, render_tiny, tiny_scene
from convsss.bench.lights import EMITTERS, write_envmap
from convsss.media.dicts import BOUNDARIES
from convsss.pipeline.params import SPECULARS, RenderParams, available_transports
from convsss.transport.convolution import DOWNSAMPLES, SPLATS


@pytest.fixture(scope="module")
def tiny(mi, tmp_path_factory):
    """``tiny(emitter, boundary, integrator)``: the battery's scene (a 1 mm wholemilk sphere, 16x16, 1 spp)."""
    envmap = write_envmap(tmp_path_factory.mktemp("env") / "sky.exr")
    return lambda emitter="point", boundary="null", integrator=None: tiny_scene(mi, envmap, emitter, boundary,
                                                                                 integrator)


def test_the_pairwise_cases_cover_every_factor_and_every_boundary_transport_pair():
    cases = pairwise()
    assert set(cases) <= set(matrix()) and len(matrix()) == len(EMITTERS) * len(BOUNDARIES) * 5
    assert {e for e, _, _ in cases} == set(EMITTERS)
    assert {(b, t) for _, b, t in cases} == {(b, t) for b in BOUNDARIES for t in available_transports()}


@pytest.mark.slow
def test_every_boundary_and_transport_renders_each_emitter_in_turn(mi):
    rows = bench_battery(pairwise())
    assert all(row.ok for row in rows), battery_table([row for row in rows if not row.ok])


valid_params = st.fixed_dictionaries({}, optional={
    "layers": st.integers(2, 24),
    "threshold": st.floats(0.0, 0.5),
    "downsample": st.sampled_from(DOWNSAMPLES),
    "splat": st.sampled_from(SPLATS),
    "correction": st.sampled_from(("plane", "none")),
    "transport": st.sampled_from(available_transports()),
    "irradiance_samples": st.integers(1, 16),
    "sample_density": st.floats(0.25, 4.0),
    "specular": st.sampled_from(SPECULARS),
    "phong_exponent": st.floats(1.0, 500.0),
    "max_depth": st.sampled_from((-1, 1, 2, 3, 6)),
    "rr_depth": st.integers(1, 8),
    "walk_depth": st.sampled_from((0.0, 4.0, float("inf"), "auto")),
})


@pytest.mark.slow
@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(params=valid_params, emitter=st.sampled_from(EMITTERS), boundary=st.sampled_from(BOUNDARIES))
def test_random_valid_parameters_give_a_finite_non_negative_image(tiny, params, emitter, boundary):
    image = render_tiny(tiny(emitter, boundary, params))
    assert np.all(np.isfinite(image)) and image.min() >= 0


invalid_params = st.one_of(
    st.fixed_dictionaries({"layers": st.one_of(st.integers(max_value=1), st.integers(min_value=257))}),
    st.fixed_dictionaries({"threshold": st.one_of(st.floats(max_value=-1e-9), st.floats(min_value=1.0),
                                                  st.just(float("nan")))}),
    st.fixed_dictionaries({"downsample": st.floats().filter(lambda x: x not in DOWNSAMPLES)}),
    st.fixed_dictionaries({"irradiance_samples": st.integers(max_value=0)}),
    st.fixed_dictionaries({"sample_density": st.one_of(st.floats(max_value=0.0), st.just(float("inf")))}),
    st.fixed_dictionaries({"unit_mm": st.one_of(st.floats(max_value=0.0), st.just(float("nan")))}),
    st.fixed_dictionaries({"max_depth": st.one_of(st.just(0), st.integers(max_value=-2))}),
    st.fixed_dictionaries({"splat": st.text(max_size=8).filter(lambda s: s not in SPLATS)}),
    st.fixed_dictionaries({"transport": st.text(max_size=8).filter(lambda s: s not in available_transports())}),
)


@pytest.mark.slow
@settings(max_examples=60, deadline=None, derandomize=True)
@given(params=invalid_params)
def test_random_invalid_parameters_fail_in_one_line(params):
    with pytest.raises(convsss.ConvsssError) as info:
        RenderParams(**params)
    message = str(info.value)
    assert "\n" not in message and next(iter(params)) in message
