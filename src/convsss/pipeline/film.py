"""The film: the camera's samples, and their reconstruction into the image in a fixed order on every thread.

Mitsuba's render loop scatter-adds each sample into every pixel its reconstruction filter covers. Threads that add
to the same pixel add in the order they happen to run, so the image's last bits changed from run to run, and convsss
ran Mitsuba's film kernel on one thread: 40 % of a cheap walked render (issue 60). Here the render loop is convsss's
own (:func:`render`, Mitsuba's ``SamplingIntegrator.render`` step for step: samples laid out pixel by pixel as
Mitsuba's, its sampler, camera rays, channels and film), and the reconstruction is a gather (:func:`splat`): each
pixel of the crop sums, on its own lane, the samples of the pixels its filter reaches, in a fixed order. The image is
then bit-identical whatever the thread count, and the film's kernel runs on every thread. Gradients go back through
its transpose (:func:`splat_adjoint`), each sample a lane summing the pixels it reaches.

The weights are Mitsuba's coalesced ``ImageBlock.put``'s: a sample at ``x`` in pixel ``floor(x)`` reaches the
``2n + 1`` pixels ``floor(x) - n ... floor(x) + n`` along each axis, ``n = ceil(radius - 1/2)``, with weight
``f(i + 1/2 - x)`` for pixel ``i`` (``f`` the filter's, separable); under a box filter a sample counts in its own
pixel alone, with weight 1.
"""

import math

import drjit as dr

from ..backend import import_mitsuba
from .parts import pass_seed, shares

mi = import_mitsuba()


def sampled_extent(film):
    """``(size, origin)``: the pixels the camera's samples are drawn in (the crop window, and its filter's border
    where the film samples one) and the film coordinates of the first."""
    border = film.rfilter().border_size() if film.sample_border() else 0
    return film.crop_size() + 2 * border, mi.ScalarPoint2i(film.crop_offset()) - border


def camera_samples(sensor, seed, spp):
    """``spp`` camera samples per pixel of ``sensor``'s :func:`sampled_extent`, drawn with seed ``seed`` and laid out
    pixel by pixel (a pixel's samples adjacent, as Mitsuba's samplers stratify them): ``(sampler, rays, weights,
    film positions)``, the sampler to go on drawing from. Under a box filter a sample's position is its pixel's corner
    (Mitsuba's: the random offset would only add round-off)."""
    film = sensor.film()
    size, origin = sampled_extent(film)
    sampler = sensor.sampler().clone()
    sampler.set_sample_count(spp)
    sampler.set_samples_per_wavefront(spp)
    sampler.seed(seed, dr.prod(size) * spp)
    index = dr.arange(mi.UInt32, dr.prod(size) * spp) // spp
    pixel = mi.Vector2f(mi.Vector2i(mi.Int32(index % size[0]), mi.Int32(index // size[0])) + mi.Vector2i(origin))
    position = pixel + sampler.next_2d()
    scale = dr.rcp(mi.ScalarVector2f(film.crop_size()))
    offset = -mi.ScalarVector2f(film.crop_offset()) * scale
    aperture = sampler.next_2d() if sensor.needs_aperture_sample() else mi.Vector2f(0.5)
    time = mi.Float(sensor.shutter_open())
    if sensor.shutter_open_time() > 0:
        time += sampler.next_1d() * sensor.shutter_open_time()
    ray, weight = sensor.sample_ray_differential(time, 0.5, dr.fma(position, scale, offset), aperture)
    if ray.has_differentials:
        ray.scale_differential(1.0 / math.sqrt(spp))
    return sampler, ray, weight, pixel if film.rfilter().is_box_filter() else position


def channels(film, radiance, valid, aovs):
    """A sample's values in the film's channels: R, G, B, [A], the weight W (1) and the AOVs."""
    ones = dr.ones(mi.Float, dr.width(radiance))
    alpha = [dr.select(valid, 1.0, 0.0)] if mi.has_flag(film.flags(), mi.FilmFlags.Alpha) else []
    return [radiance.x, radiance.y, radiance.z, *alpha, ones, *aovs]


def _reach(film):
    """``(rfilter, box, n)``: the film's filter, whether it is a box, and the pixels ``n`` a sample reaches on each side
    of its own (module doc)."""
    rfilter = film.rfilter()
    box = rfilter.is_box_filter()
    return rfilter, box, 0 if box else math.ceil(rfilter.radius() - 0.5)


def splat(film, position, values, spp):
    """The image block of the crop window holding ``values`` (a list of channels, per sample of
    :func:`camera_samples`' layout at ``spp`` samples per pixel) reconstructed by the film's filter at ``position``
    (module doc): each pixel a lane that adds the samples reaching it in a fixed order (the pixels its filter reaches
    row by row, each pixel's samples in turn), so the sums are the same on any number of threads."""
    rfilter, box, n = _reach(film)
    size, origin = sampled_extent(film)
    crop, crop_offset = film.crop_size(), film.crop_offset()
    pixel = dr.arange(mi.UInt32, dr.prod(crop))
    x, y = mi.Int32(pixel % crop[0]), mi.Int32(pixel // crop[0])
    sources = []  # the pixels whose samples can reach this one, and whether each exists
    for dy in range(-n, n + 1):
        for dx in range(-n, n + 1):
            sx, sy = x + (crop_offset[0] - origin[0] + dx), y + (crop_offset[1] - origin[1] + dy)
            inside = (sx >= 0) & (sx < size[0]) & (sy >= 0) & (sy < size[1])
            sources.append((mi.UInt32(dr.select(inside, sy * size[0] + sx, 0)) * spp, inside))
    centre = mi.Vector2f(mi.Vector2i(x, y) + mi.Vector2i(crop_offset)) + 0.5

    def body(s, *sums):
        sums = list(sums)
        for first, inside in sources:
            index = first + s
            if box:
                weight = mi.Float(1.0)
            else:
                weight = (rfilter.eval(centre.x - dr.gather(mi.Float, position.x, index, inside), inside)
                          * rfilter.eval(centre.y - dr.gather(mi.Float, position.y, index, inside), inside))
            for c, value in enumerate(values):
                sums[c] = dr.fma(weight, dr.gather(mi.Float, value, index, inside), sums[c])
        return (s + 1, *sums)

    state = (mi.UInt32(0), *[dr.zeros(mi.Float, dr.width(pixel)) for _ in values])
    sums = dr.while_loop(state, lambda s, *_: s < spp, body, labels=("s", *[f"c{c}" for c in range(len(values))]),
                         label="convsss film")[1:]
    dr.eval(sums)  # one kernel for every channel (each scatter below would launch the loop again)
    tensor = dr.zeros(mi.Float, dr.width(pixel) * len(values))
    for c, total in enumerate(sums):
        dr.scatter(tensor, total, pixel * len(values) + c)
    return mi.ImageBlock(mi.TensorXf(tensor, (crop[1], crop[0], len(values))), crop_offset, rfilter)


def image(film, position, values, spp):
    """The film's developed image (H, W, channels) of ``values`` alone (:func:`splat`), the film left empty."""
    film.clear()
    film.put_block(splat(film, position, values, spp))
    developed = film.develop()
    dr.eval(developed)
    film.clear()
    return developed


def splat_adjoint(film, position, spp, gradient):
    """The adjoint of :func:`image` for R, G and B: per sample (:func:`camera_samples`' layout at ``spp`` samples per
    pixel, at ``position``), the derivative of ``sum(gradient * image)`` (``gradient`` a tensor of the image's shape)
    with respect to its R, G and B values, ``sum_q f_q gradient[q] / W[q]`` over the pixels ``q`` of the crop its filter
    reaches, ``f_q`` its weight there and ``W[q]`` the pixel's summed weights (the film divides by them). Each sample a
    lane, in a fixed order: the same bits on any number of threads."""
    rfilter, box, n = _reach(film)
    size, origin = sampled_extent(film)
    crop, crop_offset = film.crop_size(), film.crop_offset()
    width = dr.width(position)
    source = dr.arange(mi.UInt32, width) // spp
    x, y = mi.Int32(source % size[0]) + origin[0], mi.Int32(source // size[0]) + origin[1]  # film coordinates
    weights = splat(film, position, [dr.ones(mi.Float, width)], spp).tensor().array  # W per pixel of the crop
    count, values = gradient.shape[2], gradient.array
    adjoint = dr.zeros(mi.Color3f, width)
    for dy in range(-n, n + 1):
        for dx in range(-n, n + 1):
            qx, qy = x + dx - crop_offset[0], y + dy - crop_offset[1]  # crop coordinates of the pixel reached
            inside = (qx >= 0) & (qx < crop[0]) & (qy >= 0) & (qy < crop[1])
            pixel = mi.UInt32(dr.select(inside, qy * crop[0] + qx, 0))
            reach = mi.Float(1.0) if box else (rfilter.eval(mi.Float(x + dx) + 0.5 - position.x, inside)
                                                * rfilter.eval(mi.Float(y + dy) + 0.5 - position.y, inside))
            total = dr.gather(mi.Float, weights, pixel, inside)
            scale = dr.select(inside & (total != 0.0), reach / total, 0.0)
            for c in range(3):
                adjoint[c] += scale * dr.gather(mi.Float, values, pixel * count + c, inside)
    return adjoint


def render(sample, sensor, seed, spp, most, stop, develop=True):
    """Mitsuba's ``SamplingIntegrator.render`` of ``sample(sampler, rays)`` (``(radiance, valid, aovs)``) through
    ``sensor``'s film, in as few parts of at most ``most`` samples per pixel as may be, part ``k`` drawn with seed
    :func:`~.parts.pass_seed` ``(seed, k)``, each added to the film (its weights too: the parts' image is the one of
    all their samples) and evaluated before the next, until ``stop()``. Returns the developed image, or an empty
    tensor with the film holding it when not ``develop``."""
    film = sensor.film()
    for k, share in enumerate(shares(spp, parts=-(-spp // most))):  # as few as may be, of equal size
        if stop():
            break
        sampler, rays, weight, position = camera_samples(sensor, pass_seed(seed, k), share)
        radiance, valid, aovs = sample(sampler, rays)
        film.put_block(splat(film, position, channels(film, weight * radiance, valid, aovs), share))
        film.schedule_storage()
        dr.eval()
    if not develop:
        return mi.TensorXf()
    developed = film.develop()
    dr.eval(developed)
    return developed
