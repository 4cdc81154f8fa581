"""Materials named in scene files: ``<medium type="convsss_medium">`` with a preset, or a colour + mean free path."""

import warnings

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.media.dicts import boundary_dict
from convsss.media.named import ColorModelWarning, forget, named_medium, named_medium_of
from convsss.pipeline.objects import find_translucent_objects
from convsss.profiles import model_profile
from convsss.profiles.models import COLOR_MODELS, color_of
from convsss.scene.loading import load_scene
from convsss.scene.xmlwriter import scene_to_xml


def _same_material(a, b):
    assert np.array_equal(a.sigma_s_prime, b.sigma_s_prime) and np.array_equal(a.sigma_a, b.sigma_a)
    assert a.eta == b.eta


def _named(scene, medium, boundary="null", eta=1.3):
    """``scene`` (a dict) with its object's interior replaced by a convsss_medium of ``medium``'s properties."""
    obj = {**scene["object"], "interior": {"type": "convsss_medium", **medium}, "bsdf": boundary_dict(boundary, eta)}
    return {**scene, "object": obj}


def _material(mi, source, unit_mm=1.0, profile="", total="exact"):
    return find_translucent_objects(mi, load_scene(source), unit_mm, profile, total)[0].material


@pytest.mark.slow
@pytest.mark.parametrize("boundary", ["null", "dielectric", "roughdielectric"])
def test_a_preset_by_name_is_the_cli_preset(mi, tmp_path, boundary):
    """XML and dict: exactly the Material of `--mesh bunny --material skin1`."""
    from convsss.scene.quick import demo_mesh, quick_scene
    from convsss.scene.source import SceneSource

    source = SceneSource(mesh="bunny", material="skin1", size_mm=10, boundary=boundary, width=16, height=16)
    cli = find_translucent_objects(mi, source.load())[0].material
    scene = _named(quick_scene(demo_mesh(), convsss.material("skin1"), 10, 16, 16, boundary=boundary),
                   {"preset": "Skin 1"}, boundary, 1.3)
    path = tmp_path / "named.xml"
    path.write_text(scene_to_xml(scene))
    assert '<medium type="convsss_medium" name="interior">' in path.read_text()
    for source in (scene, path):
        _same_material(_material(mi, source), cli)


@pytest.mark.parametrize("unit_mm", [1.0, 0.25, 10.0])
def test_a_preset_converts_to_scene_units(mi, sphere_scene, unit_mm):
    """A preset named with unit_mm is the medium `translucent` writes in those units: the same Material in 1/mm."""
    written = sphere_scene("marble", boundary="dielectric", unit_mm=unit_mm)
    named = _named(written, {"preset": "marble", "unit_mm": unit_mm}, "dielectric", convsss.material("marble").eta)
    _same_material(_material(mi, named, unit_mm), _material(mi, written, unit_mm))
    params = mi.traverse(load_scene(named).shapes()[0].interior_medium())
    assert float(params["scale"]) == pytest.approx(float(np.max(convsss.material("marble").sigma_t_prime)) * unit_mm)


@pytest.mark.slow
@pytest.mark.parametrize("model", COLOR_MODELS)
def test_color_and_mfp_round_trip(mi, sphere_scene, model):
    """The render-side material's total reflectance under the colour's model (the exact total, or a model's own) is
    the colour (1e-3), its reduced mean free path the mfp (float32 coefficients in the scene), with mm converted to
    scene units; rendering at that total does not warn."""
    color, mfp = [0.8, 0.5, 0.3], [1.0, 2.0, 4.0]
    unit_mm = 0.5
    profile, total = ("", "exact") if model == "exact" else (model, "model")
    scene = _named(sphere_scene(unit_mm=unit_mm, integrator={"profile": profile, "profile_total": total}),
                   {"color": {"type": "rgb", "value": color}, "mfp_mm": {"type": "rgb", "value": mfp},
                    "model": model, "eta": 1.4, "unit_mm": unit_mm}, "dielectric", 1.4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ColorModelWarning)
        made = _material(mi, scene, unit_mm, profile, total)
    np.testing.assert_allclose(color_of(made, model), color, atol=1e-3)
    np.testing.assert_allclose(made.mfp_mm, mfp, rtol=1e-5)
    assert made.eta == pytest.approx(1.4)


def test_colour_in_xml_forms(mi, tmp_path, sphere_scene):
    """rgb, float and 'R,G,B' string colours; one mfp for all channels; the default model (the exact total) and eta
    (1.3)."""
    base = scene_to_xml(sphere_scene(boundary="dielectric"))
    materials = []
    for colour in ('<rgb name="color" value="0.6, 0.6, 0.6"/>', '<float name="color" value="0.6"/>',
                   '<string name="color" value="0.6,0.6,0.6"/>'):
        medium = (f'<medium type="convsss_medium" name="interior">{colour}<float name="mfp_mm" value="1.5"/>'
                  '</medium>')
        start, end = base.index('<medium type="homogeneous"'), base.index("</medium>") + len("</medium>")
        path = tmp_path / "colour.xml"
        path.write_text(base[:start] + medium + base[end:])
        materials.append(_material(mi, path))
    for made in materials:
        _same_material(made, materials[0])
        np.testing.assert_allclose(color_of(made, "exact"), 0.6, atol=1e-3)
        np.testing.assert_allclose(made.mfp_mm, 1.5, rtol=1e-5)


@pytest.mark.slow
def test_mitsuba_users_path_renders_with_volpathmis_and_convsss(mi, tmp_path, sphere_scene, object_mask):
    """mi.load_file after convsss.register(): the medium is Mitsuba's homogeneous one, which volpathmis renders; the
    convsss integrator renders the same scene."""
    from convsss.pipeline.reference import reference_integrator

    scene_dict = _named(sphere_scene(res=32, spp=4), {"preset": "skin1"})
    path = tmp_path / "skin.xml"
    path.write_text(scene_to_xml(scene_dict))
    scene = convsss.register().load_file(str(path))
    medium = scene.shapes()[0].interior_medium()
    assert medium.class_name() == "HomogeneousMedium" and named_medium_of(mi, medium).preset == "Skin1"
    mask = object_mask(scene)
    truth = np.array(mi.render(scene, integrator=reference_integrator(), spp=4))[..., :3]
    ours = np.array(convsss.render(scene, spp=2))[..., :3]
    assert mask.any() and truth[mask].mean() > 0 and ours[mask].mean() > 0


def test_the_registry_lock_is_never_held_while_dr_jit_evaluates(mi, monkeypatch):
    """The suite hung once loading the example scene: a constructor held the registry's lock while the medium's
    fingerprint waited for Dr.Jit, and that wait ran the scene's other constructor on the same thread, which asked
    for the lock. The fingerprint (the only Dr.Jit evaluation here) now runs with the lock free."""
    from pathlib import Path

    from convsss.media import named

    held = []
    fingerprint = named._fingerprint
    monkeypatch.setattr(named, "_fingerprint", lambda *args: held.append(named._LOCK.locked()) or fingerprint(*args))
    load_scene(Path(__file__).parents[2] / "examples" / "skin_preset.xml", width=8, height=8)
    assert len(held) >= 2 and not any(held)


def test_the_example_scene_names_a_preset_and_a_colour(mi):
    from pathlib import Path

    example = Path(__file__).parents[2] / "examples" / "skin_preset.xml"
    scene = load_scene(example, width=32, height=24)
    objects = {o.name: o for o in find_translucent_objects(mi, scene)}
    bunny = objects["bunny"].material
    skin = convsss.material("skin1")
    np.testing.assert_allclose(bunny.sigma_s_prime, skin.sigma_s_prime, rtol=1e-6)
    np.testing.assert_allclose(bunny.sigma_a, skin.sigma_a, rtol=1e-5)
    ball = objects["ball"].material
    np.testing.assert_allclose(model_profile("dipole", ball).total_reflectance, [0.8, 0.45, 0.3], atol=1e-3)
    np.testing.assert_allclose(ball.mfp_mm, 2.0, rtol=1e-5)
    assert objects["ball"].eta == pytest.approx(1.3) and objects["bunny"].eta == pytest.approx(1.3)


# ---- Errors ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("medium, message", [
    ({"preset": "skn1"}, "convsss_medium: unknown material 'skn1'; did you mean 'Skin1'"),
    ({"color": [1.2, 0.5, 0.3], "mfp_mm": 1.0}, "colour 1.2 in channel R is not reachable"),
    ({"color": [0.5, 0.0, 0.3], "mfp_mm": 1.0}, "colour 0.0 in channel G is not reachable"),
    ({"color": 0.5, "mfp_mm": 0.0}, "mfp_mm=[0.0, 0.0, 0.0] is not allowed: it must be finite and > 0"),
    ({"color": 0.5, "mfp_mm": [1.0, -1.0, 1.0]}, "it must be finite and > 0"),
    ({"color": "0.5,0.4", "mfp_mm": 1.0}, "give one number or three"),
    ({"color": {"type": "constvolume", "value": 0.5}, "mfp_mm": 1.0}, "color as a ConstVolume is not supported"),
    ({"color": 0.5, "mfp_mm": 1.0, "eta": {"type": "checkerboard"}}, "convsss_medium: eta="),
    ({"color": 0.5}, "color without mfp_mm"),
    ({"preset": "skin1", "sigma_t": 1.0}, "a preset and coefficients (sigma_t) given"),
    ({"color": 0.5, "mfp_mm": 1.0, "scale": 2.0}, "color + mfp_mm and coefficients (scale) given"),
    ({"preset": "skin1", "color": 0.5, "mfp_mm": 1.0}, "both a preset and color/mfp_mm"),
    ({"preset": "skin1", "eta": 1.5}, "eta goes with color and mfp_mm"),
    ({"color": 0.5, "mfp_mm": 1.0, "model": "dipol"}, "colour model 'dipol' is not allowed"),
    ({"preset": "skin1", "unit_mm": 0.0}, "unit_mm=0.0 is not allowed"),
    ({"preset": "skin1", "colour": 0.5}, "unknown property 'colour'"),
    ({}, "nothing given"),
])
def test_bad_media_fail_in_one_line(mi, sphere_scene, medium, message):
    with pytest.raises(ConvsssError) as info:
        load_scene(_named(sphere_scene(), medium))
    assert message in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ConvsssError, match="convsss_medium: "):
        named_medium(medium)


@pytest.mark.parametrize("medium, boundary, eta, message", [
    ({"preset": "skin1"}, "dielectric", 1.5, "has eta 1.3, but its dielectric boundary has int_ior/ext_ior 1.5"),
    ({"color": 0.5, "mfp_mm": 1.0}, "roughdielectric", 1.33, "or the medium eta 1.33"),
    ({"color": 0.5, "mfp_mm": 1.0}, "null", 1.0, "is inverted at eta 1.3, but its boundary is null"),
])
def test_a_boundary_that_disagrees_is_refused(mi, sphere_scene, medium, boundary, eta, message):
    """On loading (what `convsss reference` checks) and on rendering (what the integrator finds)."""
    scene = _named(sphere_scene(), medium, boundary, eta)
    with pytest.raises(ConvsssError, match="translucent shape 'object': its convsss_medium") as info:
        load_scene(scene)
    assert message in str(info.value)
    loaded = convsss.register().load_dict(scene, optimize=False)  # a Mitsuba user's path
    with pytest.raises(ConvsssError, match="translucent shape 'object'"):
        find_translucent_objects(mi, loaded)


def test_null_boundary_takes_a_preset_and_a_colour_at_eta_1(mi, sphere_scene):
    _same_material(_material(mi, _named(sphere_scene(), {"preset": "skin1"})), _material(mi, sphere_scene()))
    made = _material(mi, _named(sphere_scene(), {"color": 0.7, "mfp_mm": 1.0, "eta": 1.0}))
    np.testing.assert_allclose(color_of(made, "exact"), 0.7, atol=1e-3)
    assert made.eta == 1.0


def test_units_of_medium_and_integrator_must_agree(mi, sphere_scene):
    scene = _named(sphere_scene(unit_mm=0.5), {"preset": "skin1", "unit_mm": 0.5})
    find_translucent_objects(mi, load_scene(scene), 0.5)
    with pytest.raises(ConvsssError, match="written for unit_mm 0.5 .* the render uses unit_mm 1"):
        find_translucent_objects(mi, load_scene(scene), 1.0)


def test_rendering_with_another_model_than_the_colours_warns(mi, sphere_scene):
    scene = load_scene(_named(sphere_scene(), {"color": 0.6, "mfp_mm": 1.0, "eta": 1.0}))
    with pytest.warns(ColorModelWarning, match="is the exact total but it renders with the pbd total"):
        find_translucent_objects(mi, scene, profile="pbd", total="model")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ColorModelWarning)
        find_translucent_objects(mi, scene, profile="pbd", total="exact")  # every model renders the exact total
    scene = load_scene(_named(sphere_scene(), {"color": 0.6, "mfp_mm": 1.0, "eta": 1.0, "model": "dipole"}))
    with pytest.warns(ColorModelWarning, match="is the dipole total but it renders with the exact total"):
        find_translucent_objects(mi, scene)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ColorModelWarning)
        find_translucent_objects(mi, scene, profile="dipole", total="model")


def test_an_edited_medium_is_no_longer_its_preset(mi, sphere_scene):
    """After the editor writes new coefficients (and forgets it), the medium is an ordinary homogeneous one."""
    scene = load_scene(_named(sphere_scene(), {"preset": "skin1"}))
    medium = scene.shapes()[0].interior_medium()
    assert named_medium_of(mi, medium) is not None
    params = mi.traverse(medium)
    params["scale"] = 2.0 * float(params["scale"])
    params.update()
    assert named_medium_of(mi, medium) is None  # its coefficients changed
    fresh = load_scene(_named(sphere_scene(), {"preset": "skin1"})).shapes()[0].interior_medium()
    forget(fresh)
    assert named_medium_of(mi, fresh) is None
