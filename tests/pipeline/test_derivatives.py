"""Derivatives of a walked render (convsss.pipeline.derivatives, issue 63): the walk's Jacobian against central
differences of the same walk on the same samples (only the weights move: near exact), Mitsuba's dr.backward and
dr.forward through mi.render against each other and against differences of volpathmis within their noise, and the
one-line refusals of what is not differentiated."""

import numpy as np
import pytest

import convsss
from convsss.bench.gradients import CASES, difference, gradient, scene_dict
from convsss.errors import ConvsssError
from convsss.pipeline.derivatives import NOT_WALKED
from convsss.pipeline.film import camera_samples

RES = 12


def _scene(mi, albedo=(0.8, 0.8, 0.8), sigma_t=(2.0, 6.0, 9.0), boundary="null", light="constant", res=RES,
           **integrator):
    """Issue 63's unit sphere (:func:`convsss.bench.gradients.scene_dict`: a homogeneous medium, ``sigma_t`` per
    unit as its rgb value times a scale) in front of a camera, under a constant environment or a point light."""
    return mi.load_dict(scene_dict(albedo, sigma_t, boundary, {"type": "convsss", "walk_depth": "inf", **integrator},
                                   res, light))


def _walk(mi, scene):
    integrator, sensor = scene.integrator(), scene.sensors()[0]
    integrator.prepare(scene, sensor, 0)
    return integrator.session.tracer.walk, sensor


def _sums(color):
    """Per channel, the sum over the lanes of a mi.Color3f."""
    return np.array(color, dtype=np.float64).sum(axis=1)


@pytest.mark.parametrize("boundary, light, sigma_t", [
    ("null", "constant", (2.0, 6.0, 9.0)),
    pytest.param("null", "constant", (4.0, 4.0, 4.0), marks=pytest.mark.slow),
    pytest.param("dielectric", "point", (2.0, 6.0, 9.0), id="dielectric-point-W4", marks=pytest.mark.slow),
    pytest.param("roughdielectric", "constant", (3.0, 5.0, 8.0), marks=pytest.mark.slow),
])
def test_the_walks_jacobian_is_the_derivative_of_its_own_estimate(mi, boundary, light, sigma_t):
    """Eq. G2 against central differences of the same walk on the same samples, its medium weighed by trial
    coefficients (RandomWalk.weigh: the paths stay, only their weights move): every channel of d/d sigma_t and
    d/d sigma_s within 0.2 % (measured 1e-4). Without roulette, whose survival odds read the weights. Dropping the
    flights' -t, the shadow rays', Eq. W4's or a channel fails it."""
    albedo = (0.8, 0.7, 0.9)
    scene = _scene(mi, albedo, sigma_t, boundary, light, rr_depth=10**6)
    walk, sensor = _walk(mi, scene)
    medium = scene.shapes()[0].interior_medium()
    sigma_t = np.array(sigma_t)
    sigma_s = sigma_t * np.array(albedo)

    def radiance(seed=5, spp=16, jacobian=False):
        sampler, ray, _, _ = camera_samples(sensor, seed, spp)
        return walk.trace_derivatives(sampler, ray) if jacobian else walk.trace(sampler, ray)

    walk.differentiate([medium])
    _, _, jacobian = radiance(jacobian=True)
    walk.differentiate([])
    d_sigma_t, d_sigma_s = _sums(jacobian[0]), _sums(jacobian[1])
    h = 1e-3
    for derivative, moved in ((d_sigma_t, (1, 0)), (d_sigma_s, (0, 1))):
        sides = []
        for sign in (1, -1):
            walk.weigh(medium, mi.Color3f(*(sigma_t * (1 + sign * h * moved[0])).tolist()),
                       mi.Color3f(*(sigma_s * (1 + sign * h * moved[1])).tolist()))
            sides.append(_sums(radiance()[0]))
        walk.evaluated = []
        differences = (sides[0] - sides[1]) / (2 * h * (sigma_t if moved[0] else sigma_s))
        assert np.all(np.abs(differences) > 0)
        np.testing.assert_allclose(derivative, differences, rtol=2e-3)


def test_backward_and_forward_agree(mi):
    """The two modes on the same samples: the forward image's mean along a tangent equals the backward gradient's
    component along it (float sums apart)."""
    import drjit as dr

    scene = _scene(mi)  # CASES[1]'s sphere
    key = "sphere.interior_medium.albedo.value.value"
    backward = gradient(mi, CASES[1], 3, 8, RES)[0]
    params = mi.traverse(scene)
    dr.enable_grad(params[key])
    params.update()
    image = mi.render(scene, params, seed=3, seed_grad=1003, spp=8)
    dr.set_grad(params[key], mi.Color3f(1.0, 0.0, 0.0))
    dr.forward_to(image)
    tangent = np.array(dr.grad(image), dtype=np.float64)[..., :3].mean(axis=(0, 1))
    assert tangent[0] == pytest.approx(backward[0], rel=1e-4) and np.all(tangent[1:] == 0)


@pytest.mark.slow
def test_gradients_equal_differences_of_volpathmis(mi):
    """Issue 63's sphere (null boundary, constant light, chromatic sigma_t, albedo 0.8): d/d albedo and d/d sigma_t
    (its rgb value) of the image's mean by dr.backward equal central differences of volpathmis (common seeds) within
    both estimates' noise (4 standard errors from the seeds' spread) and 5 %."""
    cases = [CASES[1], CASES[3]]  # d/d albedo and d/d sigma_t, both of sigma_t 2/6/9
    ours = np.array([[gradient(mi, case, seed, 256)[0] for case in cases] for seed in range(6)])
    differences = np.array([[difference(mi, case, seed, 512) for case in cases] for seed in range(6)])
    for k in range(2):
        a, b = ours[:, k].mean(0), differences[:, k].mean(0)
        noise = np.hypot(ours[:, k].std(0), differences[:, k].std(0)) / np.sqrt(6)
        assert np.all(np.abs(a - b) < np.maximum(4 * noise, 0.0)), (cases[k][0], a, b, noise)
        assert np.all(np.abs(a - b) < 0.05 * np.abs(b) + 4 * noise), (cases[k][0], a, b, noise)


def _refusal(mi, scene, key):
    import drjit as dr

    params = mi.traverse(scene)
    dr.enable_grad(params[key])
    params.update()
    image = mi.render(scene, params, spp=1)
    with pytest.raises(Exception) as raised:
        dr.backward(dr.mean(dr.ravel(image)))
    chain, error = [], raised.value
    while error is not None:
        chain.append(error)
        error = error.__cause__ or error.__context__
    return next(e for e in chain if isinstance(e, ConvsssError))


def test_a_render_that_does_not_walk_refuses_gradients(mi):
    """The transport has no derivatives: one line, never a wrong gradient (issue 63, item 1)."""
    error = _refusal(mi, _scene(mi, walk_depth=0.0), "sphere.interior_medium.albedo.value.value")
    assert str(error) == NOT_WALKED


def test_a_render_that_keeps_the_transport_on_some_object_refuses_gradients(mi, object_pair):
    """auto walks the skin sphere and renders the marble one by its transport, which has no derivatives: refused as
    a render that does not walk, even for the walked medium's."""
    scene, _ = object_pair
    error = _refusal(mi, scene, "skin.interior_medium.albedo.value.value")
    assert str(error) == NOT_WALKED


def test_a_fit_beside_an_object_auto_keeps_by_its_transport_walks_every_object(mi, object_pair):
    """auto renders the marble sphere by its transport and walks the skin one (issue 60): a fit of the skin walks,
    every object to its end (the transport's exitance has no derivatives), and a fit of the marble uses the
    transport, as the default render does."""
    import math

    from convsss.fitting import _forward_model

    scene, _ = object_pair
    skin = _forward_model(mi, scene, 0, "skin", False, 0, 4)
    assert skin.walks and skin.integrator.params.walk_depth == math.inf
    assert not skin.integrator.session.mode.transported
    marble = _forward_model(mi, scene, 0, "object", False, 0, 4)
    assert not marble.walks and marble.integrator.params.walk_depth == 0.0


@pytest.mark.parametrize("key", ["light.intensity.value", "sphere.bsdf.eta"])
def test_a_parameter_other_than_the_medium_and_the_roughness_is_refused_by_name(mi, key):
    """A light's, the boundary's index (it bends the paths: not a weight) or any other parameter with gradients on
    would read 0 or wrong: refused, named."""
    scene = _scene(mi, boundary="roughdielectric", light="point")
    error = _refusal(mi, scene, key)
    assert key in str(error) and "nothing else" in str(error)


@pytest.mark.slow
def test_derivatives_follow_convsss_render(mi):
    """convsss.render (the one-line errors' wrapper of mi.render) passes the derivatives through."""
    import drjit as dr

    scene = _scene(mi)
    params = mi.traverse(scene)
    key = "sphere.interior_medium.albedo.value.value"
    dr.enable_grad(params[key])
    params.update()
    dr.backward(dr.mean(dr.ravel(convsss.render(scene, params, spp=2))))
    assert np.all(np.array(dr.grad(params[key])) > 0)


@pytest.mark.slow
def test_roulette_keeps_the_estimate_and_its_derivatives(mi):
    """The walk's roulette (from rr_depth 5) against none, on the same sphere: d/d sigma_s within 4 standard errors.
    Before the survivors' 1/q weighed the light sampled at the vertex before it (Eq. W2's other technique), the two
    weights summed below 1: the image read 0.2 % low and this derivative 3 % (10 standard errors)."""
    means = []
    for rr_depth in (5, 10**6):
        scene = _scene(mi, res=16, rr_depth=rr_depth)
        walk, sensor = _walk(mi, scene)
        walk.differentiate([scene.shapes()[0].interior_medium()])
        per_seed = []
        for seed in range(8):
            sampler, ray, _, _ = camera_samples(sensor, seed, 256)
            per_seed.append(np.array(walk.trace_derivatives(sampler, ray)[2][1], dtype=np.float64).mean(axis=1))
        means.append((np.mean(per_seed, axis=0), np.std(per_seed, axis=0) / np.sqrt(len(per_seed))))
    (a, a_error), (b, b_error) = means
    assert np.all(np.abs(a - b) < 4 * np.hypot(a_error, b_error)), (a, b, a_error, b_error)


def _grid_scene(mi, grid, sigma_t_grid=False):
    """The unit sphere of a heterogeneous medium: an albedo ``gridvolume`` over its box and a constant sigma_t (or a
    grid of it)."""
    T = mi.ScalarTransform4f
    box = T().translate([-1.1, -1.1, -1.1]).scale(2.2)
    sigma_t = ({"type": "gridvolume", "grid": mi.VolumeGrid(np.full((2, 2, 2, 1), 0.5, np.float32)), "to_world": box}
               if sigma_t_grid else {"type": "constvolume", "value": {"type": "rgb", "value": [0.3, 0.6, 1.0]},
                                     "to_world": box})
    return mi.load_dict({
        "type": "scene", "integrator": {"type": "convsss", "walk_depth": "inf", "rr_depth": 10**6},
        "sensor": {"type": "perspective", "fov": 30.0,
                   "to_world": T().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": RES, "height": RES, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": 4}},
        "sphere": {"type": "sphere", "radius": 1.0, "bsdf": {"type": "null"},
                   "interior": {"type": "heterogeneous", "scale": 6.0, "sigma_t": sigma_t,
                                "albedo": {"type": "gridvolume", "grid": mi.VolumeGrid(grid), "to_world": box}}},
        "light": {"type": "constant"}})


@pytest.mark.slow
def test_an_albedo_grid_s_gradient_is_the_derivative_of_the_walk(mi):
    """A heterogeneous medium's albedo (a 4^3 RGB gridvolume, sigma_t constant): dr.backward of the image's sum (the
    walks replayed, Eq. G3) along a random direction of the grid equals central differences of the same walks on the
    same samples (measured 49.6139 against 49.6138)."""
    import drjit as dr

    grid = (0.6 + 0.35 * np.random.default_rng(1).random((4, 4, 4, 3))).astype(np.float32)
    scene = _grid_scene(mi, grid)
    params, key, spp, seed = mi.traverse(scene), "sphere.interior_medium.albedo.data", 8, 7
    dr.enable_grad(params[key])
    params.update()
    image = mi.render(scene, params, seed=0, seed_grad=seed, spp=spp)
    dr.backward(dr.sum(dr.ravel(image[..., :3])))
    gradient = np.array(dr.grad(params[key]), dtype=np.float64)
    dr.disable_grad(params[key])
    params.update()
    walk, sensor = _walk(mi, scene)
    direction = np.random.default_rng(3).standard_normal(grid.shape)

    def total(values):
        params[key] = mi.TensorXf(values.astype(np.float32))
        params.update()
        sampler, ray, _, _ = camera_samples(sensor, seed, spp)
        return float(np.array(walk.trace(sampler, ray)[0], dtype=np.float64).sum()) / spp  # a pixel: its samples' mean

    h = 1e-3
    differences = (total(grid + h * direction) - total(grid - h * direction)) / (2 * h)
    assert np.count_nonzero(gradient) > gradient.size // 2  # the corners of the grid lie outside the sphere
    assert float(np.sum(gradient * direction)) == pytest.approx(differences, rel=2e-3)


@pytest.mark.parametrize("case", ["sigma_t grid", "forward"])
def test_what_an_albedo_grid_does_not_give_is_refused(mi, case):
    """A varying extinction (differential ratio tracking is not built) and dr.forward of an albedo grid: one line."""
    import drjit as dr

    grid = np.full((2, 2, 2, 3), 0.8, np.float32)
    scene = _grid_scene(mi, grid, sigma_t_grid=case == "sigma_t grid")
    params, key = mi.traverse(scene), "sphere.interior_medium.albedo.data"
    dr.enable_grad(params[key])
    params.update()
    image = mi.render(scene, params, spp=1)
    with pytest.raises(Exception) as raised:
        if case == "forward":
            dr.forward(params[key])
        else:
            dr.backward(dr.mean(dr.ravel(image)))
    chain, error = [], raised.value
    while error is not None:
        chain.append(str(error))
        error = error.__cause__ or error.__context__
    wanted = "ratio tracking" if case == "sigma_t grid" else "dr.forward through a heterogeneous medium's albedo"
    assert any(wanted in message for message in chain), chain


@pytest.mark.slow
def test_a_rough_boundary_s_roughness_gradient_agrees_with_differences_of_volpathmis(mi):
    """The rough dielectric's alpha (its walks replayed, Eq. G3 at each boundary event): dr.backward of the image's
    mean against central differences of volpathmis (common seeds), 8 seeds, within 4 standard errors. Its gradients
    are noisy (the BSDF's score in alpha has long tails): measured -0.058 +- 0.004 against -0.050 +- 0.001 over 32
    seeds of 256 spp; a sign or a factor of 2 wrong fails here."""
    import drjit as dr

    from convsss.pipeline.reference import reference_integrator

    key, ours, differences = "sphere.bsdf.alpha.value", [], []
    for seed in range(8):
        scene = _scene(mi, (0.8, 0.7, 0.9), (3.0, 5.0, 8.0), "roughdielectric")
        params = mi.traverse(scene)
        dr.enable_grad(params[key])
        params.update()
        image = mi.render(scene, params, seed=seed, seed_grad=seed + 1000, spp=128)
        dr.backward(dr.mean(dr.ravel(image[..., :3])))
        ours.append(float(np.array(dr.grad(params[key])).ravel()[0]))
        dr.disable_grad(params[key])
        sides = []
        for alpha in (0.21, 0.19):
            params[key] = mi.Float(alpha)
            params.update()
            rendered = mi.render(scene, integrator=reference_integrator(), seed=seed, spp=512)
            sides.append(float(np.array(rendered, dtype=np.float64)[..., :3].mean()))
        differences.append((sides[0] - sides[1]) / 0.02)
    noise = np.hypot(np.std(ours), np.std(differences)) / np.sqrt(len(ours))
    assert np.mean(differences) < 0
    assert abs(np.mean(ours) - np.mean(differences)) < 4 * noise, (np.mean(ours), np.mean(differences), noise)
