import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.files import atomic_write
from convsss.image import (
    exr_writer,
    mask_png_writer,
    read_image,
    read_layers,
    srgb_encode,
    tonemap,
    write_exr,
    write_png,
)


def test_exr_roundtrip_is_lossless(tmp_path):
    rgb = np.random.default_rng(0).random((7, 5, 3)).astype(np.float32) * 10
    path = write_exr(tmp_path / "a.exr", rgb)
    np.testing.assert_array_equal(read_image(path), rgb)
    assert [p.name for p in tmp_path.iterdir()] == ["a.exr"]  # no temporary file left


def test_png_roundtrip_decodes_srgb(tmp_path):
    rgb = np.linspace(0, 1, 4 * 4 * 3).reshape(4, 4, 3)
    back = read_image(write_png(tmp_path / "a.png", rgb, method="none"))
    np.testing.assert_allclose(back, rgb, atol=0.01)


def test_reinhard_maps_log_average_to_key():
    lum = np.full((8, 8, 3), 5.0)
    out = tonemap(lum, "reinhard", key=0.18)
    # Uniform image: scaled luminance 0.18 = L_white, so L_d = 0.18 (1 + 1/0.18) / 1.18.
    np.testing.assert_allclose(out, 0.18 * (1 + 1 / 0.18) / 1.18, rtol=1e-6)
    assert np.all(np.diff(tonemap(np.linspace(0.01, 100, 30).reshape(1, 30, 1).repeat(3, 2))[0, :, 0]) > 0)


def test_anchor_keys_the_operator():
    """Reinhard's operator keys itself on each image, so a render and a reference 4x brighter look alike; keyed on
    one anchor they keep their ratio: the scale is the anchor's key / log-average, the white point its maximum."""
    rng = np.random.default_rng(2)
    reference = rng.random((6, 6, 3)) + 0.1
    render = 0.25 * reference
    np.testing.assert_allclose(tonemap(render), tonemap(reference), rtol=1e-4)  # up to the 1e-6 in log(1e-6 + L)
    alike = tonemap(render, anchor=reference)
    assert np.all(alike < tonemap(reference))
    # Low luminances map to about scale * L: a quarter of the reference's display values, where both are small.
    dim = reference.sum(axis=2) < 0.6
    np.testing.assert_allclose(alike[dim], 0.25 * tonemap(reference)[dim], rtol=0.2)
    # The exposure scales the anchor too: the pair's relation does not change.
    np.testing.assert_allclose(tonemap(render, exposure=2.0, anchor=reference), alike, rtol=1e-4)
    np.testing.assert_allclose(tonemap(reference, anchor=reference), tonemap(reference), rtol=0)


def test_exposure_and_encoding():
    np.testing.assert_allclose(tonemap(np.full((1, 1, 3), 0.25), "exposure", exposure=1), 0.5)
    assert srgb_encode(np.array([0.0, 1.0, 0.5])).tolist() == [0, 255, 188]


def test_exr_with_aov_channels_reads_back_by_layer(tmp_path):
    """Named channels (the integrator's AOVs) land in the EXR; read_image gives its R, G, B, read_layers every layer
    by the name before the dot."""
    values = np.random.default_rng(1).random((6, 5, 8)).astype(np.float32)
    names = ["R", "G", "B", "exitance.R", "exitance.G", "exitance.B", "object.I", "sss.mask.Y"]
    path = atomic_write(tmp_path / "aovs.exr", exr_writer(values, names))
    np.testing.assert_array_equal(read_image(path), values[..., :3])
    layers = read_layers(path)
    assert sorted(layers) == ["", "exitance", "object", "sss.mask"]
    np.testing.assert_array_equal(layers[""], values[..., :3])
    np.testing.assert_array_equal(layers["exitance"], values[..., 3:6])
    np.testing.assert_array_equal(layers["object"][..., 0], values[..., 6])
    np.testing.assert_array_equal(layers["sss.mask"][..., 0], values[..., 7])
    plain = write_exr(tmp_path / "plain.exr", values)  # no names: R, G, B only, as before
    assert list(read_layers(plain)) == [""] and read_image(plain).shape == (6, 5, 3)


@pytest.mark.parametrize("names", [["R", "G", "B", "mask.Y"], ["exitance.R", "R", "G", "B", "x.Y"],
                                   ["R", "G", "B", "a.Y", "a.Y"]])
def test_exr_channel_names_must_fit(names):
    with pytest.raises(ConvsssError, match="5 image channels need as many distinct names, R, G, B first"):
        exr_writer(np.zeros((2, 2, 5)), names)


def test_mask_png_reads_back_as_the_coverage(tmp_path):
    coverage = np.array([[0.0, 0.25, 0.5], [0.75, 1.0, 1.5]])
    path = atomic_write(tmp_path / "mask.png", mask_png_writer(coverage))
    back = read_image(path)
    np.testing.assert_allclose(back[..., 0], np.clip(coverage, 0, 1), atol=0.005)
    assert back[0, 0, 0] == 0.0 and back[1, 1, 0] == 1.0 and np.all(back[..., 0] == back[..., 2])


def test_failed_write_leaves_nothing(tmp_path):
    with pytest.raises(ConvsssError):
        write_exr(tmp_path / "b.exr", np.zeros((4, 4)))
    with pytest.raises(ConvsssError, match="tone mapping"):
        write_png(tmp_path / "b.png", np.zeros((4, 4, 3)), method="filmic")
    assert list(tmp_path.iterdir()) == []


def test_missing_image():
    with pytest.raises(ConvsssError, match="does not exist"):
        read_image("/nonexistent/x.exr")


@pytest.mark.parametrize("settings, message", [
    ({"key": 0.0}, "key=0.0"), ({"key": -1.0}, "key=-1.0"), ({"key": float("nan")}, "key=nan"),
    ({"key": float("inf")}, "key=inf"), ({"exposure": float("nan")}, "exposure=nan"),
    ({"exposure": float("-inf"), "method": "exposure"}, "exposure=-inf"),
])
def test_bad_tone_mapping_settings_fail_before_writing(tmp_path, settings, message):
    with pytest.raises(ConvsssError, match=message):
        tonemap(np.ones((2, 2, 3)), **settings)
    with pytest.raises(ConvsssError, match=message):
        write_png(tmp_path / "a.png", np.ones((2, 2, 3)), **settings)
    assert list(tmp_path.iterdir()) == []
