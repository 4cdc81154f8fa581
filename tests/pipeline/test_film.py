"""The film (:mod:`convsss.pipeline.film`): its reconstruction is Mitsuba's ``ImageBlock.put``'s, summed per pixel in a
fixed order, and a render through it is Mitsuba's render loop's."""

import drjit as dr
import numpy as np
import pytest

import convsss


def _sensor(mi, rfilter, crop=None, border=False, pixel_format="rgb", width=13, height=9):
    film = {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": rfilter},
            "pixel_format": pixel_format, "sample_border": border}
    if crop is not None:
        film.update(crop_offset_x=crop[0], crop_offset_y=crop[1], crop_width=crop[2], crop_height=crop[3])
    return mi.load_dict({"type": "perspective", "film": film, "sampler": {"type": "independent"}})


@pytest.mark.parametrize("rfilter", ["box", "gaussian", "tent", "lanczos", "mitchell"])
@pytest.mark.parametrize("crop, border", [(None, False), ((3, 2, 7, 5), False), ((3, 2, 7, 5), True)])
def test_the_splat_is_mitsubas_put_summed_in_a_fixed_order(mi, rfilter, crop, border):
    """Random values at the camera samples' positions (5 per pixel, the crop window and border Mitsuba's render loop
    draws them in), reconstructed by :func:`splat` and by Mitsuba's coalesced ``ImageBlock.put`` (as its render loop
    does), agree to float round-off, negative lobes (Lanczos, Mitchell) and the crop's edges included."""
    from convsss.pipeline import film as films

    sensor = _sensor(mi, rfilter, crop, border, pixel_format="rgba")
    film = sensor.film()
    film.prepare(["extra.Y"])
    _, _, _, position = films.camera_samples(sensor, 7, 5)
    rng = np.random.default_rng(1)
    n = dr.width(position)
    values = [mi.Float(rng.uniform(-0.5, 2.0, n).astype(np.float32)) for _ in range(film.prepare(["extra.Y"]))]
    ours = films.splat(film, position, values, 5).tensor().numpy()
    block = film.create_block()
    block.set_offset(film.crop_offset())
    block.put(position, values)
    theirs = block.tensor().numpy()
    assert ours.shape == theirs.shape == (film.crop_size()[1], film.crop_size()[0], len(values))
    np.testing.assert_allclose(ours, theirs, rtol=1e-5, atol=1e-5 * np.abs(theirs).max())


def test_the_splat_sums_the_same_bits_on_any_number_of_threads(mi):
    """The same samples splatted on one thread and on eight: the same bytes (Mitsuba's scatter-adds differ in the
    last bits from run to run on several)."""
    from convsss.pipeline import film as films

    sensor = _sensor(mi, "gaussian", width=40, height=30)
    film = sensor.film()
    film.prepare([])
    _, _, _, position = films.camera_samples(sensor, 3, 16)
    rng = np.random.default_rng(2)
    values = [mi.Float(rng.uniform(0.0, 1.0, dr.width(position)).astype(np.float32)) for _ in range(4)]
    threads = dr.thread_count()
    images = []
    try:
        for count in (1, 8):
            dr.set_thread_count(count)
            images.append(films.splat(film, position, values, 16).tensor().numpy().tobytes())
    finally:
        dr.set_thread_count(threads)
    assert images[0] == images[1]


@pytest.mark.slow
def test_a_render_in_parts_is_the_render_of_all_their_samples(mi, sphere_scene):
    """``samples_per_pass`` splits a render into parts added to one film: the parts' image weighs each pixel's
    samples as one render of all of them would (the filter's weights summed), so the transport's image at 4 spp in
    parts of 1 (seeds of their own) is within noise of one render of 4, and equals none of its parts."""
    scene = mi.load_dict(sphere_scene(res=24, spp=4))
    whole = np.array(convsss.render(scene, seed=5))
    parted = mi.load_dict(sphere_scene(res=24, spp=4, integrator={"samples_per_pass": 1}))
    parts = np.array(convsss.render(parted, seed=5))
    assert parts.shape == whole.shape
    lit = whole[..., :3].sum(axis=2) > 0
    assert lit.sum() > 50
    assert abs(parts[lit].mean() / whole[lit].mean() - 1.0) < 0.02
    assert not np.array_equal(parts, whole)


def test_a_render_not_developed_leaves_its_image_in_the_film(mi, sphere_scene):
    """``develop=False`` (Mitsuba's): an empty tensor back, the film holding what ``develop()`` turns into the image a
    developed render of the same seed gives."""
    scene = mi.load_dict(sphere_scene(res=16, spp=2))
    integrator, sensor = scene.integrator(), scene.sensors()[0]
    image = np.array(integrator.render(scene, sensor, seed=3))
    empty = integrator.render(scene, sensor, seed=3, develop=False)
    assert dr.width(empty.array) == 0
    np.testing.assert_array_equal(np.array(sensor.film().develop()), image)


@pytest.mark.parametrize("rfilter", [pytest.param("box", marks=pytest.mark.slow), "gaussian",
                                     pytest.param("lanczos", marks=pytest.mark.slow)])
@pytest.mark.parametrize("crop, border", [(None, False), ((3, 2, 7, 5), True)])
def test_the_splat_adjoint_is_the_derivative_of_the_developed_image(mi, rfilter, crop, border):
    """:func:`splat_adjoint` against Dr.Jit's reverse derivative of Mitsuba's ``put`` and ``develop`` (how the
    gradients were taken before) for random values, positions and image gradients: the same to float round-off."""
    from convsss.pipeline import film as films

    sensor = _sensor(mi, rfilter, crop, border, pixel_format="rgba")
    film = sensor.film()
    count = film.prepare(["extra.Y"])
    _, _, _, position = films.camera_samples(sensor, 11, 4)
    rng = np.random.default_rng(3)
    n = dr.width(position)
    crop_size = film.crop_size()
    gradient = mi.TensorXf(rng.normal(size=(crop_size[1], crop_size[0], count - 1)).astype(np.float32))
    ours = films.splat_adjoint(film, position, 4, gradient)
    with dr.resume_grad():
        rgb = mi.Color3f(*[mi.Float(rng.uniform(0.1, 1.0, n).astype(np.float32)) for _ in range(3)])
        dr.enable_grad(rgb)
        block = film.create_block()
        block.set_offset(film.crop_offset())
        ones = dr.ones(mi.Float, n)
        block.put(position, [rgb.x, rgb.y, rgb.z, ones, ones, dr.zeros(mi.Float, n)])
        film.clear()
        film.put_block(block)
        developed = film.develop()
        dr.backward_from(dr.sum(developed * gradient, axis=None))
        theirs = dr.grad(rgb)
    for c in range(3):
        expected = np.array(theirs[c])
        np.testing.assert_allclose(np.array(ours[c]), expected, rtol=1e-4, atol=1e-5 * np.abs(expected).max())
