"""The reliability battery (issue 9): every emitter type x boundary x transport on a tiny scene, and random valid and
invalid integrator parameters. Every run ends in a finite, non-negative image or in one line of ConvsssError."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import convsss
from convsss.bench.lights import EMITTERS, emitter_dict, write_envmap
from convsss.pipeline.params import SPECULARS, RenderParams, available_transports
from convsss.scene.materials import BOUNDARIES, translucent
from convsss.transport.convolution import DOWNSAMPLES, SPLATS


@pytest.fixture(scope="module")
def tiny(mi, tmp_path_factory):
    """``tiny(emitter, boundary, integrator)``: a 1 mm wholemilk sphere, 16x16 pixels, 1 spp, box filter."""
    envmap = write_envmap(tmp_path_factory.mktemp("env") / "sky.exr")
    T = mi.ScalarTransform4f

    def make(emitter="point", boundary="null", integrator=None, material="wholemilk"):
        return mi.load_dict({
            "type": "scene",
            "integrator": {"type": "convsss", "sample_density": 1.0, "irradiance_samples": 4, **(integrator or {})},
            "sensor": {"type": "perspective", "fov": 35,
                       "to_world": T().look_at(origin=[0, 1, 5], target=[0, 0, 0], up=[0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": 1}},
            "object": translucent({"type": "sphere"}, convsss.material(material), boundary=boundary),
            "floor": {"type": "rectangle", "to_world": T().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(10)},
            "light": emitter_dict(emitter, 1.0, envmap),
        })

    return make


def _render(scene):
    image = np.array(scene.integrator().render(scene, scene.sensors()[0], seed=1), dtype=np.float64)
    return image[..., :3]




@pytest.mark.slow
@pytest.mark.parametrize("transport", sorted(available_transports()))
@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("emitter", EMITTERS)
def test_every_emitter_boundary_and_transport_renders(tiny, emitter, boundary, transport):
    image = _render(tiny(emitter, boundary, {"transport": transport}))
    assert np.all(np.isfinite(image)) and image.min() >= 0
    assert image[6:10, 6:10].mean() > 0  # the sphere, in the middle of the frame, is lit


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
})


@pytest.mark.slow
@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(params=valid_params, emitter=st.sampled_from(EMITTERS), boundary=st.sampled_from(BOUNDARIES))
def test_random_valid_parameters_give_a_finite_non_negative_image(tiny, params, emitter, boundary):
    image = _render(tiny(emitter, boundary, params))
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
