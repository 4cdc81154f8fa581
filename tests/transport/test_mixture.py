"""Eq. H1 over every registered transport: one class is the plain transport; classes of one profile, whatever their
weights, are too (both sums of Eq. H1 are linear in the weights, which sum to 1); relit, a mixture answers as one
built for the new irradiance; two classes of different profiles lie between them."""

import numpy as np
import pytest

from convsss import material
from convsss.profiles import model_profile
from convsss.samples import IrradianceSamples, ViewFrame
from convsss.transport import TRANSPORTS, make_transport
from convsss.transport.mixture import MixtureTransport

FRAME = ViewFrame.look_at(origin=[0, 0, 50], target=[0, 0, 0])
#: The grid transports take seconds per build here, and a mixture builds several: the full suite runs them.
KINDS = [pytest.param(k, marks=pytest.mark.slow) if k in ("convolution", "volume") else k for k in sorted(TRANSPORTS)]
#: The convolution transport skips layers under a threshold of the largest, which is not linear in the irradiance.
LINEAR = {"convolution": {"threshold": 0.0}}


def _make(kind):
    """``make(samples, profile, medium)``: the transport ``kind`` of one class."""
    return lambda samples, profile, medium: make_transport(kind, samples, profile, FRAME, medium,
                                                           **LINEAR.get(kind, {}))


def _sphere(n=1500, radius=2.0, seed=0):
    k = np.arange(n) + 0.5
    phi, theta = np.arccos(1 - 2 * k / n), np.pi * (1 + 5**0.5) * k
    normal = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    lit = np.maximum(normal @ np.array([0.6, 0.0, 0.8]), 0.0)[:, None] * np.random.default_rng(seed).uniform(
        0.5, 1.0, (n, 3))
    return IrradianceSamples(normal * radius, 4 * np.pi * radius**2 / n, lit, normal)


def _weights(samples, count, seed=1):
    w = np.random.default_rng(seed).uniform(0.0, 1.0, (len(samples), count, 3))
    return w / w.sum(axis=1, keepdims=True)


@pytest.mark.parametrize("kind", KINDS)
def test_one_profile_in_any_classes_is_the_plain_transport(kind):
    samples = _sphere()
    skin = model_profile("dipole", material("skin1"))
    plain = _make(kind)(samples, skin, material("skin1"))
    points, normals = samples.position[::7], samples.normal[::7]
    expected = plain.exitance(points, normals)
    one = MixtureTransport(samples, [skin], np.ones((len(samples), 1, 3)), _make(kind), [material("skin1")])
    np.testing.assert_allclose(one.exitance(points, normals), expected, rtol=1e-12)
    # Split over three classes, the approximate transports build other clusters, cells and layers: within their
    # accuracy (the exact sum is linear to rounding)
    three = MixtureTransport(samples, [skin] * 3, _weights(samples, 3), _make(kind), [material("skin1")] * 3)
    np.testing.assert_allclose(three.exitance(points, normals), expected, rtol=1e-9 if kind == "exact" else 0.01)


@pytest.mark.parametrize("kind", KINDS)
def test_relit_mixture_answers_as_one_built_for_the_new_light(kind):
    samples, other = _sphere(seed=0), _sphere(seed=5)
    media = [material(name) for name in ("skin1", "marble")]
    profiles = [model_profile("dipole", m) for m in media]
    weights = _weights(samples, 2)
    relit = MixtureTransport(samples, profiles, weights, _make(kind), media).relit(other.irradiance)
    built = MixtureTransport(other, profiles, weights, _make(kind), media)
    points = samples.position[::11]
    np.testing.assert_allclose(relit.exitance(points), built.exitance(points), rtol=1e-9)
    assert relit.stats["classes"] == 2 and relit.stats["samples"] == len(samples)


def test_two_classes_lie_between_their_media():
    """A lit plane of two media, one for x < 0 and one for x > 0 (weights 0 or 1): the exitance lies between the two
    homogeneous planes' at every point, and is each pure one's four diffusion lengths from the seam."""
    spacing, half = 0.4, 20.0
    xs = (np.arange(int(2 * half / spacing)) + 0.5) * spacing - half
    x, y = (a.ravel() for a in np.meshgrid(xs, xs))
    position = np.stack([x, y, np.zeros_like(x)], axis=1)
    samples = IrradianceSamples(position, spacing**2, np.ones((len(x), 3)), np.tile([0.0, 0.0, 1.0], (len(x), 1)))
    media = [material(name) for name in ("skin1", "skin2")]
    profiles = [model_profile("dipole", m) for m in media]
    left = (x < 0).astype(float)
    weights = np.stack([left, 1 - left], axis=1)[:, :, None] * np.ones(3)
    mixed = MixtureTransport(samples, profiles, weights, _make("exact"), media)
    pure = [make_transport("exact", samples, p, FRAME) for p in profiles]
    row = np.flatnonzero(np.abs(y) < spacing)
    points, normals = position[row], samples.normal[row]
    m = mixed.exitance(points, normals)
    a, b = (t.exitance(points, normals) for t in pure)
    assert np.all(m >= np.minimum(a, b) * (1 - 1e-9)) and np.all(m <= np.maximum(a, b) * (1 + 1e-9))
    assert not np.allclose(a, b, rtol=0.05)
    reach = 4 * max(m.diffusion_length_mm.max() for m in media)
    far = np.abs(points[:, 0]) > reach
    own = np.where((points[:, 0] < 0)[:, None], a, b)
    np.testing.assert_allclose(m[far], own[far], rtol=0.01)
