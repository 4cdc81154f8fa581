"""Jumps across the deep interior (convsss.pipeline.jumps): the sphere's exit table against an independent walk, the
clearance a lower bound of the distance to the surface, the margin by the lights, and auto's walks with jumps equal
to the same walks without them and to volpathmis."""

import numpy as np
import pytest

from convsss.pipeline.jumps import MARGIN, MU_BINS, RADII, TABLE_PATHS, clearance_grid, exit_table, margin
from convsss.pipeline.objects import find_translucent_objects
from convsss.pipeline.reference import reference_integrator, translucent_pixels

from .test_walk import _lights


def _independent_exits(radius, albedo, paths, rng):
    """Walks from the centre of a sphere of ``radius`` mean free paths (isotropic scattering, vectorised numpy,
    analog absorption): per walk whether it left collided, its exit cosine to the normal, and whether it left."""
    def isotropic(n):
        z = rng.uniform(-1.0, 1.0, n)
        phi = rng.uniform(0.0, 2.0 * np.pi, n)
        r = np.sqrt(1.0 - z * z)
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)

    x, d = np.zeros((paths, 3)), isotropic(paths)
    alive, left, collided = np.ones(paths, bool), np.zeros(paths, bool), np.zeros(paths, bool)
    mu = np.zeros(paths)
    scattered = np.zeros(paths, bool)
    while alive.any():
        i = np.flatnonzero(alive)
        t = rng.exponential(size=i.size)
        b = np.einsum("ij,ij->i", x[i], d[i])
        s = -b + np.sqrt(b * b - np.einsum("ij,ij->i", x[i], x[i]) + radius**2)
        out = s <= t
        exit_point = x[i[out]] + s[out, None] * d[i[out]]
        mu[i[out]] = np.einsum("ij,ij->i", exit_point, d[i[out]]) / radius
        left[i[out]], collided[i[out]], alive[i[out]] = True, scattered[i[out]], False
        stay = i[~out]
        x[stay] += t[~out, None] * d[stay]
        absorbed = rng.uniform(size=stay.size) >= albedo
        alive[stay[absorbed]] = False
        go = stay[~absorbed]
        scattered[go] = True
        d[go] = isotropic(go.size)
    return collided, mu, left


@pytest.mark.parametrize("radius, albedo", [(2.0, 0.8), (4.0, 0.99)])
def test_the_exit_table_is_an_independent_walks_exit(radius, albedo):
    """Eq. J1's collided part: its total (the share of light that leaves the sphere after scattering) and its mean
    exit cosine equal those of analog walks written apart, within both estimates' noise."""
    uncollided, table = exit_table([radius], albedo)
    assert uncollided[0] == pytest.approx(np.exp(-radius))
    paths = 40_000
    collided, mu, left = _independent_exits(radius, albedo, paths, np.random.default_rng(1))
    share = np.count_nonzero(left & collided) / paths
    noise = np.sqrt(share * (1 - share) / paths) + np.sqrt(share / TABLE_PATHS)
    assert table[0].sum() == pytest.approx(share, abs=4 * noise)
    centres = (np.arange(MU_BINS) + 0.5) / MU_BINS
    ours = float(centres @ table[0] / table[0].sum())
    theirs = mu[left & collided]
    binned = (np.minimum((theirs * MU_BINS).astype(int), MU_BINS - 1) + 0.5) / MU_BINS  # the table's bins
    assert ours == pytest.approx(binned.mean(), abs=4 * binned.std() / np.sqrt(theirs.size) + 0.005)


def test_without_absorption_every_walk_leaves():
    uncollided, table = exit_table(RADII[:3], 1.0, paths=4096)
    assert np.allclose(uncollided + table.sum(axis=1), 1.0)


def _sphere_mesh(mi, radius, n=64):
    """A latitude-longitude mesh of a sphere (inside it, by at most its sagitta)."""
    import drjit as dr

    theta, phi = np.meshgrid(np.linspace(0.0, np.pi, n + 1), np.linspace(0.0, 2.0 * np.pi, 2 * n + 1), indexing="ij")
    points = radius * np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], -1)
    index = np.arange(points.shape[0] * points.shape[1]).reshape(points.shape[:2])
    quads = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], -1).reshape(-1, 4)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    mesh = mi.Mesh("sphere", points.shape[0] * points.shape[1], len(faces))
    params = mi.traverse(mesh)
    params["vertex_positions"] = dr.ravel(mi.Point3f(*points.reshape(-1, 3).T.astype(np.float32)))
    params["faces"] = dr.ravel(mi.Vector3u(*faces.T.astype(np.uint32)))
    params.update()
    return mesh


@pytest.mark.parametrize("kind", ["sphere", "mesh"])
def test_the_clearance_is_a_lower_bound_of_the_distance_to_the_surface(mi, kind):
    """On a sphere of radius 2 (analytic, and a mesh of it), at points inside: never above the distance to the
    surface, and within a few cells of it."""
    shape = mi.load_dict({"type": "sphere", "radius": 2.0}) if kind == "sphere" else _sphere_mesh(mi, 2.0)
    spacing = 0.1
    values, origin = clearance_grid([(shape, np.identity(4))], np.full(3, -2.0), np.full(3, 2.0), spacing)
    points = np.random.default_rng(0).uniform(-2.0, 2.0, (20000, 3))
    bound = values[tuple(np.rint((points - origin) / spacing).astype(int).T)]  # the nearest node's
    distance = np.abs(2.0 - np.linalg.norm(points, axis=1))  # the mesh lies inside: its distance is no more
    assert np.all(bound <= distance + 1e-9)
    inside = np.linalg.norm(points, axis=1) < 1.5
    assert np.all(distance[inside] - bound[inside] < 5 * spacing)


@pytest.mark.parametrize("boundary, light, kept", [
    ("null", "point", MARGIN),  # the light sampled inside: the margin
    ("roughdielectric", "point", 0.0),  # a rough boundary stops every shadow ray from inside
    ("dielectric", "environment", 0.0),  # a uniform environment is left to the paths that hit it
    ("dielectric", "point", MARGIN),  # a point light by Eq. W5
])
def test_the_margin_is_kept_where_light_is_sampled_inside(mi, sphere_scene, boundary, light, kept):
    scene = mi.load_dict(sphere_scene(material="skin1", radius=10.0, boundary=boundary, emitters=_lights(mi, light,
                                                                                                         10.0)))
    obj = find_translucent_objects(mi, scene, lights_inside=True)[0]
    assert margin(scene, obj, []) == kept


def test_no_jumps_in_an_object_with_a_light_inside(mi, sphere_scene):
    light = {"light": {"type": "point", "position": [0.0, 0.0, 0.0], "intensity": {"type": "rgb", "value": [1.0] * 3}}}
    scene = mi.load_dict(sphere_scene(material="skin1", radius=10.0, emitters=light))
    assert margin(scene, find_translucent_objects(mi, scene, lights_inside=True)[0], []) is None


def _jumping_scene(mi, sphere_scene, boundary, light, floor=True):
    """A 20 mm skin1 sphere (15 mean free paths in red, walked by auto: its reduced albedo is below diffusion's)."""
    return mi.load_dict(sphere_scene(material="skin1", radius=20.0, boundary=boundary, res=24, floor=floor,
                                     emitters=_lights(mi, light, 20.0)))


@pytest.mark.parametrize("boundary, light", [("null", "point"), ("roughdielectric", "area")])
def test_walks_with_jumps_render_the_walks_without(mi, sphere_scene, boundary, light):
    """The same mean over the object as every event walked (four seeds each, within four standard errors and 1 %),
    with jumps taken and fewer events."""
    scene = _jumping_scene(mi, sphere_scene, boundary, light)
    means, stats = {}, {}
    for jumps in ("on", "off"):
        walk = mi.load_dict({"type": "convsss", "jumps": jumps})
        images = [np.array(mi.render(scene, integrator=walk, spp=64, seed=s), dtype=np.float64) for s in range(4)]
        means[jumps] = np.array([image.mean(axis=(0, 1)) for image in images])
        stats[jumps] = walk.stats["walk"]
    assert stats["on"]["jumps"] > 0 and stats["off"]["jumps"] == 0
    assert stats["on"]["events_per_path"] < stats["off"]["events_per_path"]
    on, off = means["on"].mean(axis=0), means["off"].mean(axis=0)
    error = np.hypot(means["on"].std(axis=0, ddof=1), means["off"].std(axis=0, ddof=1)) / 2
    assert np.all(np.abs(on - off) <= 0.01 * off + 4 * error), on / off


@pytest.mark.slow
def test_walks_with_jumps_are_volpathmis(mi, sphere_scene):
    """Over the object's pixels (the area light in view has pixels of its edge whose coverage two seeds tell badly):
    the mean within 1 % and four standard errors, each pixel within the seeds' noise."""
    scene = _jumping_scene(mi, sphere_scene, "roughdielectric", "area", floor=False)
    walk = mi.load_dict({"type": "convsss", "max_depth": -1})
    ours = [np.array(mi.render(scene, integrator=walk, spp=256, seed=s), dtype=np.float64)[..., :3] for s in (1, 2)]
    assert walk.stats["walk"]["jumps"] > 0
    reference = reference_integrator()
    truth = [np.array(mi.render(scene, integrator=reference, spp=256, seed=s), dtype=np.float64)[..., :3]
             for s in (3, 4)]
    inside = translucent_pixels(scene)
    ours, truth = [image[inside] for image in ours], [image[inside] for image in truth]
    mean, noise = {}, {}
    for name, (a, b) in (("ours", ours), ("truth", truth)):
        mean[name] = (a + b).mean(axis=0) / 2
        noise[name] = np.sqrt(np.mean((a - b) ** 2, axis=0) / 4 / len(a))
    assert np.all(np.abs(mean["ours"] - mean["truth"]) <= 0.01 * mean["truth"]
                  + 4 * np.hypot(noise["ours"], noise["truth"])), mean["ours"] / mean["truth"]
    spread = np.mean((ours[0] - ours[1]) ** 2 + (truth[0] - truth[1]) ** 2) / 4
    assert np.mean(((ours[0] + ours[1]) / 2 - (truth[0] + truth[1]) / 2) ** 2) <= 1.3 * spread


def test_an_explicit_inf_takes_no_jumps(mi, sphere_scene):
    scene = _jumping_scene(mi, sphere_scene, "roughdielectric", "area")
    walk = mi.load_dict({"type": "convsss", "walk_depth": "inf"})
    mi.render(scene, integrator=walk, spp=2)
    assert walk.stats["walk"]["jumps"] == 0


def test_tables_are_kept_between_processes_whole(tmp_path, monkeypatch):
    """Made once and read back after; a broken file is made again, not read."""
    from convsss.pipeline import jumps

    monkeypatch.setenv("CONVSSS_CACHE", str(tmp_path))
    calls = []

    def make():
        calls.append(1)
        return {"a": np.arange(3.0)}

    assert np.array_equal(jumps._kept("t.npz", make)["a"], np.arange(3.0))
    assert np.array_equal(jumps._kept("t.npz", make)["a"], np.arange(3.0))
    assert len(calls) == 1
    (tmp_path / "jumps" / "t.npz").write_bytes(b"broken")
    assert np.array_equal(jumps._kept("t.npz", make)["a"], np.arange(3.0))
    assert len(calls) == 2
