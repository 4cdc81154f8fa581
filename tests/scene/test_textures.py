"""A surface colour from a texture (:mod:`convsss.scene.textures`): a ``convsss_medium`` whose ``color`` is a bitmap
is made, at the load, as the heterogeneous medium of Eq. T1 (the medium at a point is the inverted colour of the
nearest surface point), which convsss renders through its classes and ``volpathmis`` as it is; a uniform texture
is its constant colour; bad textures, meshes without texture coordinates and instanced textured media are refused in
one line."""

import warnings

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.media.dicts import boundary_dict
from convsss.media.named import TextureWarning, named_medium_of
from convsss.pipeline.media import CLASS_STEP, MediumField
from convsss.pipeline.objects import find_translucent_objects
from convsss.profiles.models import albedo_from_reflectance
from convsss.scene.loading import load_scene

RADIUS = 10.0
#: The stripes' colours: u < 1/2 (the sphere's azimuth in [0, pi)) and above.
LEFT, RIGHT = (0.7, 0.5, 0.4), (0.3, 0.2, 0.15)


def _bitmap(mi, path, left, right, width=64, height=32):
    """An EXR of colour ``left`` for u < 1/2 and ``right`` above (linear values)."""
    u = (np.arange(width) + 0.5) / width
    image = np.where((u < 0.5)[None, :, None], left, right) * np.ones((height, width, 3))
    mi.Bitmap(image.astype(np.float32)).write(str(path))
    return str(path)


def _scene(sphere_scene, color, mfp_mm=1.0, eta=1.3, shape=None, res=24):
    scene = sphere_scene(radius=RADIUS, res=res, boundary="dielectric")
    scene["object"] = {**(shape or scene["object"]), "bsdf": boundary_dict("dielectric", eta),
                       "interior": {"type": "convsss_medium", "color": color, "mfp_mm": mfp_mm, "eta": eta}}
    return scene


def _texture(path):
    return {"type": "bitmap", "filename": path}


def _render(mi, scene):
    return np.array(convsss.render(load_scene(scene), seed=0), dtype=np.float64)[..., :3]


def test_a_uniform_texture_is_its_constant_colour(mi, sphere_scene, tmp_path):
    """Its equivalent is a constant volume: the homogeneous medium of the colour within the inversion's table
    (``1 - alpha'`` within 3e-4 relative), and the same image within that."""
    color = (0.6, 0.4, 0.3)
    textured = _scene(sphere_scene, _texture(_bitmap(mi, tmp_path / "u.exr", color, color)))
    constant = _scene(sphere_scene, {"type": "rgb", "value": list(color)})
    (a,), (b,) = (find_translucent_objects(mi, load_scene(s)) for s in (textured, constant))
    assert a.classes is None
    np.testing.assert_allclose(1 - a.material.albedo_prime, 1 - b.material.albedo_prime, rtol=3e-4)
    np.testing.assert_allclose(a.material.sigma_t_prime, b.material.sigma_t_prime, rtol=1e-6)
    images = [_render(mi, s) for s in (textured, constant)]
    assert images[1].max() > 0
    np.testing.assert_allclose(images[0], images[1], atol=3e-4 * images[1].max())


def test_the_equivalent_medium_is_eq_t1(mi, sphere_scene, tmp_path):
    """Inside the sphere, away from the stripes' seams, the medium is each stripe's colour inverted (the root found
    by brentq), constant with depth; volpathmis renders that very medium (the shape's interior is heterogeneous)."""
    scene = load_scene(_scene(sphere_scene, _texture(_bitmap(mi, tmp_path / "s.exr", LEFT, RIGHT)), mfp_mm=2.0))
    medium = scene.shapes()[0].interior_medium()
    assert medium.class_name() == "HeterogeneousMedium"
    assert named_medium_of(mi, medium).textured
    field = MediumField(medium, 1.0, 0.0, "object")
    # Mitsuba's sphere: u = azimuth / (2 pi) about z from +x, so u < 1/2 is y > 0
    for sign, color in ((1.0, LEFT), (-1.0, RIGHT)):
        points = np.array([[0.3 * sign, sign, 0.1], [-0.3 * sign, sign, -0.2]]) / np.sqrt(1.1)
        for depth in (0.9, 0.6):
            sigma_s_prime, sigma_a = field.coefficients(points * depth * RADIUS)
            albedo = sigma_s_prime / (sigma_s_prime + sigma_a)
            np.testing.assert_allclose(albedo, np.tile(albedo_from_reflectance("exact", color, 1.3), (2, 1)),
                                       rtol=1e-4)
            np.testing.assert_allclose(sigma_s_prime + sigma_a, 0.5, rtol=1e-6)


def test_stripes_make_classes_between_their_colours(mi, sphere_scene, tmp_path):
    """Two colours make classes whose ends lie near the two stripes' materials (within a quarter of a class step in
    the classes' coordinate, 1/2 log(1 - alpha'): Eq. H2 reaches across the seam where the diffusion length is long);
    the render lies between those of the two colours alone."""
    textured = _scene(sphere_scene, _texture(_bitmap(mi, tmp_path / "s.exr", LEFT, RIGHT)))
    (obj,) = find_translucent_objects(mi, load_scene(textured))
    assert obj.classes is not None and len(obj.class_profiles) >= 2
    ends = np.sort([1 - obj.classes.materials[k].albedo_prime for k in (0, -1)], axis=0)  # per channel: each
    stripes = np.sort([1 - albedo_from_reflectance("exact", c, 1.3) for c in (LEFT, RIGHT)], axis=0)  # its own axis
    assert np.all(np.abs(0.5 * np.log(ends / stripes)) < 0.25 * CLASS_STEP)
    images = {name: _render(mi, s) for name, s in (
        ("textured", textured), ("left", _scene(sphere_scene, {"type": "rgb", "value": list(LEFT)})),
        ("right", _scene(sphere_scene, {"type": "rgb", "value": list(RIGHT)})))}
    means = {name: image.reshape(-1, 3).mean(axis=0) for name, image in images.items()}
    assert np.all(means["right"] < means["textured"]) and np.all(means["textured"] < means["left"])


def test_loaded_outside_load_scene_it_is_the_mean_colour_and_says_so(mi, sphere_scene, tmp_path):
    scene = _scene(sphere_scene, _texture(_bitmap(mi, tmp_path / "s.exr", LEFT, RIGHT)))
    with pytest.warns(TextureWarning, match="mean colour"):
        loaded = mi.load_dict(scene, optimize=False)
    assert loaded.shapes()[0].interior_medium().class_name() == "HomogeneousMedium"
    with warnings.catch_warnings():
        warnings.simplefilter("error", TextureWarning)
        load_scene(scene)


def _uvless_cube(tmp_path):
    path = tmp_path / "cube.obj"
    corners = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    path.write_text("\n".join([f"v {a} {b} {c}" for a, b, c in corners]
                              + [f"f {a} {b} {c}\nf {a} {c} {d}" for a, b, c, d in faces]) + "\n")
    return str(path)


@pytest.mark.parametrize("case, words", [
    ("black texel", "the color texture has values that are not finite or <= 0"),
    ("too bright", "values are not reachable by the exact total"),
    ("no uv", "has no texture coordinates (uv)"),
    ("a volume as colour", "color as a ConstVolume is not supported"),
    ("texture as eta", "convsss_medium: eta="),
    ("mfp texture <= 0", "the mfp_mm texture has values that are not finite or <= 0"),
    ("instanced", "a textured convsss_medium in a shapegroup is not supported"),
])
def test_bad_textures_are_refused_in_one_line(mi, sphere_scene, tmp_path, case, words):
    stripes = _texture(_bitmap(mi, tmp_path / "s.exr", LEFT, RIGHT))
    scene = {
        "black texel": lambda: _scene(sphere_scene, _texture(_bitmap(mi, tmp_path / "b.exr", LEFT, (0.3, 0.0, 0.1)))),
        "too bright": lambda: _scene(sphere_scene, _texture(_bitmap(mi, tmp_path / "w.exr", LEFT, (1.2, 0.9, 0.9)))),
        "no uv": lambda: _scene(sphere_scene, stripes, shape={"type": "obj", "filename": _uvless_cube(tmp_path)}),
        "a volume as colour": lambda: _scene(sphere_scene, {"type": "constvolume", "value": 0.5}),
        "texture as eta": lambda: {**_scene(sphere_scene, stripes), "object": {
            **_scene(sphere_scene, stripes)["object"], "interior": {
                "type": "convsss_medium", "color": stripes, "mfp_mm": 1.0, "eta": {"type": "checkerboard"}}}},
        "mfp texture <= 0": lambda: _scene(sphere_scene, stripes, mfp_mm=_texture(
            _bitmap(mi, tmp_path / "m.exr", (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)))),
        "instanced": lambda: {**{k: v for k, v in _scene(sphere_scene, stripes).items() if k != "object"},
                              "group": {"type": "shapegroup", "s": _scene(sphere_scene, stripes)["object"]},
                              "one": {"type": "instance", "shapegroup": {"type": "ref", "id": "group"}}},
    }[case]()
    with pytest.raises(ConvsssError) as info:
        load_scene(scene)
    assert words in str(info.value) and "\n" not in str(info.value)
