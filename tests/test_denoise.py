"""The denoiser (convsss.denoise): Open Image Denoise on independent pixel noise, guides read from the film's AOVs, and
the warning for a filter that correlates the noise."""

import warnings

import numpy as np
import pytest

from convsss.denoise import CorrelatedNoiseWarning, check_pixel_filter, denoise, guides_of
from convsss.errors import ConvsssError


def _noisy(seed=0, size=96):
    """A smooth HDR image and a noisy estimate of it (independent per pixel, mean-preserving, 50 % noise)."""
    y, x = np.mgrid[0:size, 0:size] / size
    clean = np.stack([0.2 + 0.5 * x, 0.3 + 0.2 * y, 0.1 + 0.1 * x * y], axis=-1) * 0.05
    rng = np.random.default_rng(seed)
    return clean, clean * rng.gamma(4.0, 0.25, clean.shape)


def test_independent_noise_is_removed_and_the_mean_kept():
    clean, noisy = _noisy()
    albedo, normal = np.full_like(clean, 0.6), np.broadcast_to([0.0, 0.0, 1.0], clean.shape)
    for guides in ((), (albedo,), (albedo, normal)):
        out = denoise(noisy, *guides)
        assert out.shape == clean.shape and out.dtype == np.float64
        raw, den = (np.sqrt(np.mean((img - clean) ** 2)) for img in (noisy, out))
        assert den < 0.25 * raw
        assert out.mean() == pytest.approx(noisy.mean(), rel=0.02)


def test_bad_values_are_cleaned_and_a_normal_needs_an_albedo():
    _, noisy = _noisy()
    noisy[0, 0] = np.nan, -1.0, np.inf
    assert np.all(np.isfinite(denoise(noisy)))
    with pytest.raises(ConvsssError, match="albedo"):
        denoise(noisy, None, np.zeros_like(noisy))


def test_guides_are_read_by_channel_name():
    film = np.arange(2 * 2 * 9, dtype=np.float64).reshape(2, 2, 9)
    names = ["R", "G", "B", "normal.X", "normal.Y", "normal.Z", "albedo.R", "albedo.G", "albedo.B"]
    albedo, normal = guides_of(film, names)
    np.testing.assert_array_equal(albedo, film[..., 6:9])
    np.testing.assert_array_equal(normal, film[..., 3:6])
    assert guides_of(film[..., :3], names[:3]) == (None, None)


@pytest.mark.parametrize("kind, correlated", [("box", False), ("gaussian", True), ("tent", True)])
def test_a_filter_wider_than_a_pixel_is_warned_about(mi, kind, correlated):
    scene = mi.load_dict({"type": "scene", "sensor": {"type": "perspective", "film": {
        "type": "hdrfilm", "width": 8, "height": 8, "rfilter": {"type": kind}}}})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert check_pixel_filter(scene.sensors()[0]) is not correlated
    assert [issubclass(w.category, CorrelatedNoiseWarning) for w in caught] == [True] * correlated


def test_the_brightness_that_oidn_clamps_away_is_kept():
    """A walk's light partly comes in rare bright samples, which OIDN clamps: 1.8 % dark here (7-12 % on the noisiest
    walked scenes); the denoised image keeps the raw one's mean within 0.5 %."""
    clean, _ = _noisy()
    rng = np.random.default_rng(3)
    spikes = np.where(rng.random(clean.shape[:2] + (1,)) < 0.05, 10.0, 0.0)  # 5 % of the pixels hold half the light
    noisy = clean * (0.5 + spikes)
    assert denoise(noisy).mean() == pytest.approx(noisy.mean(), rel=0.005)
