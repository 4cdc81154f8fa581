import pytest

from convsss.errors import ConvsssError
from convsss.pipeline.params import RenderParams


def test_defaults_are_the_papers_layers_and_the_multiscale_transport():
    p = RenderParams()
    assert (p.layers, p.threshold, p.downsample, p.splat) == (8, 0.001, 1.0, "linear")  # the paper's layers
    assert p.transport == "multiscale" and p.accuracy == 0.01
    assert p.integrator_dict()["type"] == "convsss"


def test_single_scattering_is_traced_unless_a_models_own_total_holds_it():
    assert RenderParams().single_scattering == "traced" and RenderParams().orders == "multiple"
    implied = RenderParams(profile_total="model")
    assert implied.single_scattering == "profile" and implied.orders == "all"
    assert RenderParams(**implied.to_dict()).single_scattering == "profile"


def test_from_mapping_takes_only_known_names():
    p = RenderParams.from_properties({"layers": 4, "downsample": 0.5, "unrelated": 1})
    assert p.layers == 4 and p.downsample == 0.5


@pytest.mark.parametrize("kwargs, message", [
    ({"layers": 1}, "layers=1"),
    ({"layers": 2.5}, "whole number"),
    ({"layers": 10000}, "layers=10000 is not allowed: it must be a whole number >= 2 and <= 256"),
    ({"threshold": -0.1}, "threshold=-0.1"),
    ({"downsample": 0.3}, "downsample=0.3"),
    ({"transport": "fft"}, "transport='fft'"),
    ({"specular": "glossy"}, "specular='glossy'"),
    ({"splat": "box"}, "splat='box'"),
    ({"unit_mm": 0}, "unit_mm=0"),
    ({"max_depth": 0}, "max_depth=0"),
    ({"irradiance_samples": 0}, "irradiance_samples=0"),
    ({"profile": "/nonexistent/profile.csv"}, "profile file"),
    ({"single_scattering": "exact"}, "single_scattering='exact'"),
    ({"single_scattering": "traced", "profile_total": "model"}, "single_scattering=traced needs profile_total=exact"),
    ({"walk_depth": "automatic"}, "walk_depth='automatic' is not allowed: it must be a number >= 0, or inf or auto"),
    ({"walk_depth": -1.0}, "walk_depth=-1"),
    ({"walk_depth": "-1"}, "walk_depth='-1'"),
    ({"walk_depth": "nan"}, "walk_depth='nan'"),
    ({"layers": "2.5"}, "whole number"),
])
def test_bad_values_say_what_is_allowed(kwargs, message):
    with pytest.raises(ConvsssError, match=message):
        RenderParams(**kwargs)


@pytest.mark.parametrize("text, value", [("inf", float("inf")), ("2", 2.0), ("0", 0.0), ("1e300", 1e300),
                                         (" auto ", "auto")])
def test_a_number_written_as_text_is_the_number(mi, text, value):
    """Issue 62: a scene file's <string name="walk_depth" value="inf"/> (or load_dict's "inf") was refused with a
    message naming it as allowed. The same value as a scene file's string, a load_dict entry and a keyword."""
    scene = mi.load_string(f"""<scene version="3.0.0"><integrator type="convsss">
        <string name="walk_depth" value="{text}"/><string name="max_depth" value="4"/></integrator></scene>""")
    assert scene.integrator().params.walk_depth == value and scene.integrator().params.max_depth == 4
    assert mi.load_dict({"type": "convsss", "walk_depth": text}).params.walk_depth == value
    assert RenderParams(walk_depth=text).walk_depth == value


def test_integrator_documents_every_parameter_from_its_declaration():
    from convsss.pipeline.integrator import ConvsssIntegrator

    doc = ConvsssIntegrator.__doc__
    for name in RenderParams.names():
        assert f" * - {name}\n" in doc, name
    assert "(Default: 8)" in doc and "(Default: 0.05)" in doc


def test_a_parameter_of_another_transport_warns_that_it_has_no_effect(mi):
    """Issue 31: the README's `{"type": "convsss", "layers": 8, "downsample": 0.5}` rendered with the multiscale
    transport, which ignores both, without a word."""
    import warnings

    from convsss.pipeline.integrator import register
    from convsss.pipeline.params import IgnoredParameterWarning

    register()
    with pytest.warns(IgnoredParameterWarning, match=r"downsample \(convolution transport\), layers \(convolution "
                                                      r"transport\): not a parameter of the multiscale transport"):
        mi.load_dict({"type": "convsss", "layers": 8, "downsample": 0.5})
    with warnings.catch_warnings():
        warnings.simplefilter("error", IgnoredParameterWarning)
        mi.load_dict({"type": "convsss", "transport": "convolution", "layers": 8, "downsample": 0.5})


def test_walk_depth_auto_walks_where_diffusion_fails_and_keeps_the_transport_where_it_holds():
    from types import SimpleNamespace

    from convsss.pipeline.params import RenderMode, render_mode, walks_alone

    holds, fails, also = (SimpleNamespace(diffusion_holds=lambda answer=answer: answer, key=(k, 0))
                          for k, answer in enumerate((True, False, False)))
    auto = RenderParams(walk_depth="auto", layers=4)
    assert auto.walk_depth == "auto"
    assert render_mode(auto, [holds, holds]) == RenderMode(0.0, straight=False)
    # Each object its own way: the one where diffusion holds keeps its transport, the other walks.
    mixed = render_mode(auto, [holds, fails])
    assert mixed == RenderMode(float("inf"), straight=True, transported=frozenset({holds.key}))
    assert mixed.transports(holds) and not mixed.transports(fails)
    assert not walks_alone(auto, mixed)  # the transported object needs stages 2-5
    walked = render_mode(auto, [fails, also])
    assert walked == RenderMode(float("inf"), straight=True) and walks_alone(auto, walked)
    assert not walked.transports(fails) and RenderMode(0.0).transports(fails)
    # Given: as it is; walks ended in the field take every light but the environment straight, those to the end
    # only what no path reaches (volpathmis).
    assert render_mode(RenderParams(walk_depth=4.0), [fails]) == RenderMode(4.0, straight=True)
    assert render_mode(RenderParams(walk_depth="inf"), [fails]) == RenderMode(float("inf"), straight=False)
    assert render_mode(RenderParams(walk_depth=0.0), [fails]) == RenderMode(0.0, straight=False)


def test_a_transport_named_renders_unless_a_walk_depth_is_named_too():
    assert RenderParams().walk_depth == "auto"
    assert RenderParams(transport="volume").walk_depth == 0.0
    assert RenderParams(transport="volume", walk_depth="auto").walk_depth == "auto"
    assert RenderParams(**RenderParams(transport="exact").to_dict()).walk_depth == 0.0
    from convsss.pipeline.params import render_params

    scene = RenderParams(walk_depth=4.0).to_dict()  # a scene's convsss integrator, every value filled in
    assert render_params({"transport": "volume", "walk_depth": None}, scene).walk_depth == 0.0
    assert render_params({"transport": "volume", "walk_depth": 2.0}, scene).walk_depth == 2.0
    assert render_params({"layers": 4}, scene).walk_depth == 4.0


def test_replace_changes_what_it_names_and_checks_it():
    p = RenderParams(walk_depth="auto", layers=4, transport="convolution")
    q = p.replace(walk_depth=2.0)
    assert (q.walk_depth, q.layers, q.transport) == (2.0, 4, "convolution") and p.walk_depth == "auto"
    with pytest.raises(ConvsssError, match="layers=1"):
        p.replace(layers=1)


def test_where_every_object_walks_the_transports_parameters_set_are_named():
    """Issue 62: --profile, --accuracy, --incidence, --single-scattering changed nothing where every object walks,
    without a word. Those set away from their defaults are named (the renderer warns with them); defaults are not."""
    from convsss.pipeline.params import walk_ignored

    assert walk_ignored(RenderParams(walk_depth="inf")) == []
    named = walk_ignored(RenderParams(walk_depth="inf", profile="pbd", incidence="normal", accuracy=0.003,
                                      single_scattering="profile", profile_total="model"))
    assert named == ["incidence", "single_scattering", "profile_total", "profile", "accuracy"]


def test_irradiance_samples_auto_gives_each_profile_area_its_directions():
    """auto: 16 directions per profile area where the profile rule draws the samples (1 a point at its default 1500
    points a profile area, 4 at 4), 16 a point without it (the paper's samples by cells); a number as given."""
    assert RenderParams().irradiance_samples == "auto" and RenderParams().directions == 1
    assert RenderParams(profile_samples=4.0).directions == 4
    assert RenderParams(profile_samples=0.0).directions == 16
    assert RenderParams(irradiance_samples=8).directions == 8
    assert RenderParams(irradiance_samples="auto", profile_samples=1.0).directions == 16
