import warnings

import numpy as np
import pytest

from convsss.pipeline.reference import BlackPassWarning, render_reference, translucent_pixels


@pytest.mark.slow
def test_passes_average_and_report(mi, sphere_scene):
    scene = mi.load_dict(sphere_scene(res=16))
    seen = []
    image = render_reference(scene, spp=5, pass_spp=2, seed=1,
                             on_pass=lambda img, done, k, n: seen.append((done, k, n, img.copy())))
    assert [s[:3] for s in seen] == [(2, 0, 3), (4, 1, 3), (5, 2, 3)]
    np.testing.assert_array_equal(image, seen[-1][3])
    assert image.shape == (16, 16, 3) and image.max() > 0
    np.testing.assert_array_equal(image, render_reference(scene, spp=5, pass_spp=2, seed=1))


@pytest.mark.slow
def test_point_light_behind_a_dielectric_warns_black(mi, sphere_scene):
    """docs/architecture.md: a point light behind a smooth dielectric is unreachable for a path tracer; the pass is
    black over the object's pixels, and says so once. The index-matched sphere under the same light does not warn."""
    dark = mi.load_dict(sphere_scene(res=16, boundary="dielectric"))
    objects = translucent_pixels(dark)
    assert objects.shape == (16, 16) and 10 < objects.sum() < 16 * 16
    with pytest.warns(BlackPassWarning, match=rf"pass 1 of 2 is black over all {objects.sum()} pixels") as seen:
        image = render_reference(dark, spp=2, pass_spp=1)
    assert len([w for w in seen if w.category is BlackPassWarning]) == 1 and not image[objects].any()
    lit = mi.load_dict(sphere_scene(res=16, boundary="null"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", BlackPassWarning)
        assert render_reference(lit, spp=1, pass_spp=1)[translucent_pixels(lit)].any()


def test_a_pixel_mitsuba_writes_nan_is_left_out_of_its_mean_with_one_warning(mi, sphere_scene, monkeypatch):
    """Issue 51: volpathmis wrote NaN pixels on a heterogeneous medium, and the ground truth carried them without a
    word. A pass's NaN pixel is the mean of its finite passes; a warning says how many."""
    import types

    from convsss.pipeline import reference

    scene = mi.load_dict(sphere_scene(res=8))
    passes = []

    def render(*args, **kwargs):
        image = np.array(mi.render(*args, **kwargs))
        if len(passes) == 1:
            image[2, 3, 1] = np.nan
        passes.append(image[..., :3].astype(np.float64))
        return image

    proxy = types.SimpleNamespace(**{name: getattr(mi, name) for name in ("load_dict", "UInt32")}, render=render)
    monkeypatch.setattr(reference, "load_mitsuba", lambda: proxy)
    with pytest.warns(reference.NonFiniteWarning, match="1 pixel"):
        image = render_reference(scene, spp=3, pass_spp=1, seed=1)
    assert np.all(np.isfinite(image))
    np.testing.assert_allclose(image[2, 3], (passes[0][2, 3] + passes[2][2, 3]) / 2)
    np.testing.assert_allclose(image[0, 0], (passes[0][0, 0] + passes[1][0, 0] + passes[2][0, 0]) / 3)
