"""Heterogeneous interiors (:mod:`convsss.pipeline.media`): a constant volume is the homogeneous medium of its values; a
varying one splits into classes whose ends are its media and whose weights sum to 1; volumes that do not cover the
object, and coefficients that are not finite, negative or scatter more than they extinguish, are refused."""

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.materials import Material
from convsss.media.dicts import medium_parameters, translucent
from convsss.pipeline.objects import find_translucent_objects

#: The spheres' radius (mm): several diffusion lengths of skin1 (at most 3.7 mm), so that the medium a surface point
#: stands for (Eq. H2, within two diffusion lengths) lies in its half of a sphere of two halves.
RADIUS = 20.0


def _grid(mi, path, values):
    mi.VolumeGrid(np.ascontiguousarray(values, dtype=np.float32)).write(str(path))
    return str(path)


def _volume(mi, filename, radius=RADIUS):
    """A gridvolume over the cube that holds the sphere of ``radius``, 10 % to spare."""
    return {"type": "gridvolume", "filename": filename,
            "to_world": mi.ScalarTransform4f().translate([-1.1 * radius] * 3).scale(2.2 * radius)}


def _sphere(mi, albedo, sigma_t, scale, radius=RADIUS):
    return {"type": "scene", "s": {"type": "sphere", "radius": radius, "bsdf": {"type": "null"},
                                   "interior": {"type": "heterogeneous", "albedo": albedo, "sigma_t": sigma_t,
                                                "scale": scale}}}


def _halves(material_left, material_right, n=16):
    """Albedo cells (n, n, n, 3), Mitsuba's z, y, x order: ``material_left`` for x < 0, ``material_right`` above."""
    left, right = (medium_parameters(m)["albedo"] for m in (material_left, material_right))
    x = (np.arange(n) + 0.5) / n
    return np.where((x < 0.5)[None, None, :, None], left, right) * np.ones((n, n, n, 3))


def test_a_constant_volume_is_the_homogeneous_medium(mi, tmp_path):
    skin = convsss.material("skin1")
    p = medium_parameters(skin)
    homogeneous = find_translucent_objects(mi, mi.load_dict({"type": "scene", "s": translucent(
        {"type": "sphere", "radius": RADIUS}, skin, boundary="null")}))[0]
    grid = _grid(mi, tmp_path / "albedo.vol", np.broadcast_to(p["albedo"].astype(np.float32), (8, 8, 8, 3)))
    sigma_t = {"type": "constvolume", "value": {"type": "rgb", "value": p["sigma_t"].tolist()},
               "to_world": _volume(mi, grid)["to_world"]}
    (obj,) = find_translucent_objects(mi, mi.load_dict(_sphere(mi, _volume(mi, grid), sigma_t, p["scale"])))
    assert obj.classes is None and obj.profiles == (obj.profile,)
    np.testing.assert_array_equal(obj.material.sigma_s_prime, homogeneous.material.sigma_s_prime)
    np.testing.assert_array_equal(obj.material.sigma_a, homogeneous.material.sigma_a)


def test_two_media_make_classes_from_one_to_the_other(mi, tmp_path):
    skin, marble = convsss.material("skin1"), convsss.material("marble")
    scale = medium_parameters(skin)["scale"]
    radius = 4 * RADIUS  # Eq. H2's reach (two diffusion lengths of marble's albedo, up to 17 mm) within its half
    grid = _grid(mi, tmp_path / "albedo.vol", _halves(skin, marble))
    volume = _volume(mi, grid, radius)
    sigma_t = {"type": "constvolume", "value": {"type": "rgb", "value": (skin.sigma_t_prime / scale).tolist()},
               "to_world": volume["to_world"]}
    (obj,) = find_translucent_objects(mi, mi.load_dict(_sphere(mi, volume, sigma_t, scale, radius)))
    classes = obj.classes
    assert classes is not None and len(classes.materials) == len(obj.class_profiles) >= 2
    # the classes run along 1 - alpha' (the mean free path is skin's throughout): the ends are skin, and marble's
    # albedo at skin's extinction
    marble_albedo = Material(skin.sigma_t_prime * marble.sigma_s_prime / marble.sigma_t_prime,
                             skin.sigma_t_prime * marble.sigma_a / marble.sigma_t_prime, 1.0)
    darker, lighter = sorted([classes.materials[0], classes.materials[-1]], key=lambda m: -m.sigma_a[0])
    for end, medium in ((darker, skin), (lighter, marble_albedo)):  # an end class is the mean of the points near
        np.testing.assert_allclose(end.sigma_a, medium.sigma_a, rtol=0.05)  # it, a few within reach of the seam
        np.testing.assert_allclose(end.sigma_t_prime, skin.sigma_t_prime, rtol=1e-5)
    points = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.99, 0.14]]) * radius
    weights = classes.weights(points, points / np.linalg.norm(points, axis=1, keepdims=True))
    assert weights.shape == (3, len(classes.materials), 3)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=1e-12)
    assert np.all(weights >= 0)
    # the points deep in each half are all of one end class
    ends_of = {int(np.argmax(weights[i, :, 0])) for i in (0, 1)}
    assert ends_of == {0, len(classes.materials) - 1}


def test_the_weights_table_reads_as_the_medium_does(mi, tmp_path):
    """The table of the weights (surface points a quarter of the shortest diffusion length apart) reads the axis
    coordinates of Eq. H2 at surface points drawn apart from it: on average within 2 % of the classes' spacing of
    Eq. H2 evaluated at each point, and per point within a quarter of it on average (what differs is mostly the
    noise of the 16 lookups a point makes, which the table's neighbours average out)."""
    from dataclasses import replace

    from convsss.pipeline.surface import sample_surface

    skin, marble = convsss.material("skin1"), convsss.material("marble")
    scale = medium_parameters(skin)["scale"]
    grid = _grid(mi, tmp_path / "albedo.vol", _halves(skin, marble))
    volume = _volume(mi, grid)
    sigma_t = {"type": "constvolume", "value": {"type": "rgb", "value": (skin.sigma_t_prime / scale).tolist()},
               "to_world": volume["to_world"]}
    (obj,) = find_translucent_objects(mi, mi.load_dict(_sphere(mi, volume, sigma_t, scale)))
    classes = obj.classes
    assert classes.table is not None and classes.table[0].n >= 4096
    position, normal, _ = sample_surface(obj.shape, 20000, seed=7)
    points, normals = (np.asarray(a, dtype=np.float64).reshape(3, -1).T for a in (position, normal))
    tabulated = classes.coordinates(points, normals)
    direct = replace(classes, table=None).coordinates(points, normals)
    spacing = np.diff(classes.nodes, axis=1)[:, 0]
    assert np.all(np.abs(tabulated.mean(axis=0) - direct.mean(axis=0)) < 0.02 * spacing)
    assert np.all(np.abs(tabulated - direct).mean(axis=0) < 0.25 * spacing)
    np.testing.assert_allclose(classes.weights(points, normals).sum(axis=1), 1.0, rtol=1e-12)


def _refusal(mi, tmp_path, values, to_world_cube=True):
    grid = _grid(mi, tmp_path / "albedo.vol", values)
    volume = _volume(mi, grid) if to_world_cube else {"type": "gridvolume", "filename": grid}
    sigma_t = {**volume, "type": "gridvolume"}
    with pytest.raises(ConvsssError) as error:
        find_translucent_objects(mi, mi.load_dict(_sphere(mi, volume, sigma_t, 5.0)))
    return str(error.value)


def test_a_volume_that_does_not_cover_the_object_is_refused(mi, tmp_path):
    message = _refusal(mi, tmp_path, np.full((4, 4, 4, 1), 0.9), to_world_cube=False)
    assert "does not cover the object" in message and "to_world" in message and "\n" not in message


@pytest.mark.parametrize("value, words", [(np.nan, "not finite"), (-0.5, "negative"), (1.5, "albedo above 1")])
def test_bad_coefficients_are_refused(mi, tmp_path, value, words):
    values = np.full((8, 8, 8, 1), 0.9)
    values[2:4, 2:4, 2:4] = value  # inside the sphere, off its surface: the lattice finds it
    message = _refusal(mi, tmp_path, values)
    assert words in message and "'s'" in message and "\n" not in message


def test_a_nan_albedo_over_a_constant_extinction_is_refused_in_one_line(mi, tmp_path):
    """Issue 51: an IndexError inside the check (a constvolume's coefficients came back once, not per point)."""
    values = np.full((8, 8, 8, 3), 0.9)
    values[3, 3, 3, 0] = np.nan
    volume = _volume(mi, _grid(mi, tmp_path / "albedo.vol", values))
    sigma_t = {"type": "constvolume", "value": {"type": "rgb", "value": [0.5] * 3}, "to_world": volume["to_world"]}
    with pytest.raises(ConvsssError, match="not finite in channel R"):
        find_translucent_objects(mi, mi.load_dict(_sphere(mi, volume, sigma_t, 5.0)))


def test_a_constant_extinction_without_a_box_is_refused_saying_why(mi):
    """Issue 51: Mitsuba takes the medium's box from sigma_t, and a constvolume's is the unit cube: say so."""
    constant = {"type": "constvolume", "value": {"type": "rgb", "value": [0.5] * 3}}
    with pytest.raises(ConvsssError, match="does not cover the object.*constvolume's is the unit cube.*homogeneous"):
        find_translucent_objects(mi, mi.load_dict(_sphere(mi, constant, constant, 5.0)))


def test_a_tabulated_profile_of_a_varying_medium_is_refused(mi, tmp_path):
    skin, marble = convsss.material("skin1"), convsss.material("marble")
    grid = _grid(mi, tmp_path / "albedo.vol", _halves(skin, marble))
    scene = mi.load_dict(_sphere(mi, _volume(mi, grid), {"type": "constvolume", "value": 1.0,
                                                          "to_world": _volume(mi, grid)["to_world"]}, 3.0))
    table = tmp_path / "profile.csv"
    table.write_text("r_mm,R,G,B\n0.1,1,1,1\n1,0.1,0.1,0.1\n10,0.001,0.001,0.001\n")
    with pytest.raises(ConvsssError, match="varies in space"):
        find_translucent_objects(mi, scene, profile=str(table))


def _render(mi, scene):
    return np.array(convsss.render(mi.load_dict(scene), seed=0), dtype=np.float64)[..., :3]


@pytest.mark.slow
def test_renders_of_a_constant_and_a_varying_volume(mi, sphere_scene, tmp_path):
    """A constant volume renders bit for bit as the homogeneous medium; a sphere of two halves renders between the two
    homogeneous spheres, each side of the image near its half's."""
    skin, marble = convsss.material("skin1"), convsss.material("marble")
    p = medium_parameters(skin)
    homogeneous = sphere_scene(material="skin1", radius=RADIUS, res=24)
    constant = _grid(mi, tmp_path / "constant.vol", np.broadcast_to(p["albedo"].astype(np.float32), (4, 4, 4, 3)))
    halves = _grid(mi, tmp_path / "halves.vol", _halves(skin, marble))
    images = {}
    for name, grid in (("constant", constant), ("halves", halves)):
        scene = sphere_scene(material="skin1", radius=RADIUS, res=24)
        volume = _volume(mi, grid)
        sigma_t = {"type": "constvolume", "value": {"type": "rgb", "value": p["sigma_t"].tolist()},
                   "to_world": volume["to_world"]}
        scene["object"]["interior"] = {"type": "heterogeneous", "albedo": volume, "sigma_t": sigma_t,
                                       "scale": p["scale"]}
        images[name] = _render(mi, scene)
    images["skin"] = _render(mi, homogeneous)
    np.testing.assert_array_equal(images["constant"], images["skin"])
    lighter = sphere_scene(radius=RADIUS, res=24)
    lighter["object"]["interior"]["albedo"] = {"type": "rgb", "value": medium_parameters(marble)["albedo"].tolist()}
    images["lighter"] = _render(mi, lighter)
    assert images["skin"].sum() < images["halves"].sum() < images["lighter"].sum()
    # each side of the image leans to its half's medium (the seam is at the centre column; light crosses it)
    ratio = sorted(images["halves"][:, sl].sum() / images["skin"][:, sl].sum() for sl in (slice(0, 10),
                                                                                           slice(14, 24)))
    gain = images["lighter"].sum() / images["skin"].sum()
    assert gain > 1.3 and ratio[1] - ratio[0] > 0.5 * (gain - 1)


def test_a_surface_point_stands_for_the_medium_below(mi, tmp_path):
    """Eq. H2 on a flat top face over two layers: a dark top half a diffusion length thick over a light body reads
    well between them; a thick one reads as the top, none as the body."""
    from convsss.pipeline.media import MediumField

    n, side = 128, 64.0  # cells of 0.5 mm over [0, 64) mm; the top face at y = 64, a layer of `top_mm` under it
    def explored(top_mm):
        albedo = np.full((n, n, n, 1), 0.999)
        albedo[:, n - int(round(top_mm * n / side)):, :] = 0.9  # (z, y, x): the cells above y = 64 - top_mm
        grid = _grid(mi, tmp_path / f"layers{top_mm}.vol", albedo)
        medium = mi.load_dict({"type": "heterogeneous", "scale": 2.0,
                               "albedo": {"type": "gridvolume", "filename": grid,
                                          "to_world": mi.ScalarTransform4f().scale(side)},
                               "sigma_t": {"type": "constvolume", "value": 1.0,
                                           "to_world": mi.ScalarTransform4f().scale(side)}})
        field = MediumField(medium, 1.0, 0.0, "layers")
        point, up = np.array([[32.0, 63.999, 32.0]]), np.array([[0.0, 1.0, 0.0]])
        return field.coefficients(point)[1][0, 0], field.explored_coefficients(point, up)[1][0, 0]

    dark, light = 2.0 * 0.1, 2.0 * 0.001  # sigma_a of the two layers (1/mm)
    surface, thick = explored(48)
    assert surface == pytest.approx(dark, rel=1e-4) and thick == pytest.approx(dark, rel=1e-4)
    surface, thin = explored(0.5)
    assert surface == pytest.approx(dark, rel=1e-4) and 10 * light < thin < 0.8 * dark
    assert explored(0)[1] == pytest.approx(light, rel=1e-4)
