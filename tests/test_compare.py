import json

import numpy as np
import pytest
from click.testing import CliRunner

from convsss.cli import cli
from convsss.compare import METRICS, block_average, compare, error_image, mask_layer, object_mask
from convsss.errors import ConvsssError
from convsss.files import atomic_write
from convsss.image import exr_writer, read_image, write_exr, write_png


def disc_image(h=48, w=64, seed=0):
    """A textured disc on a black background, and its mask."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:h, :w]
    inside = (yy - h / 2) ** 2 + (xx - w / 2) ** 2 < (0.4 * h) ** 2
    texture = 0.2 + 0.6 * rng.random((h, w, 3)) * [1.0, 0.7, 0.4]
    return np.where(inside[..., None], texture, 0.0), inside


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_identical_images_have_zero_error():
    a, inside = disc_image()
    result = compare(a, a.copy())
    assert result["pixels"] == inside.sum()
    for name in ("rmse", "relmse", "mean_rel_error"):
        assert result[name] == [0.0, 0.0, 0.0]
    assert result["mean_ratio"] == [1.0, 1.0, 1.0]
    assert result["flip_mean"] == 0.0


@pytest.mark.parametrize("scale", [0.5, 1.7])
def test_scaled_image_reports_the_scale(scale):
    a, _ = disc_image()
    result = compare(a, scale * a)
    np.testing.assert_allclose(result["mean_ratio"], scale, rtol=1e-12)
    np.testing.assert_allclose(result["mean_rel_error"], abs(scale - 1), rtol=1e-12)  # every A is above the floor
    np.testing.assert_allclose(result["relmse"], (scale - 1) ** 2, rtol=1e-3)
    assert result["flip_mean"] > 0.05


def test_metrics_match_their_definitions():
    a, inside = disc_image()
    b = a * (1 + 0.1 * np.random.default_rng(1).normal(size=a.shape))
    result = compare(a, b)
    A, B = a[inside], b[inside]
    floor = 0.01 * A.mean(axis=0)
    np.testing.assert_allclose(result["rmse"], np.sqrt(((B - A) ** 2).mean(axis=0)))
    np.testing.assert_allclose(result["relmse"], ((B - A) ** 2 / (A**2 + floor**2)).mean(axis=0))
    np.testing.assert_allclose(result["mean_rel_error"], (np.abs(B - A) / np.maximum(A, floor)).mean(axis=0))
    np.testing.assert_allclose(result["max_test"], B.max(axis=0))
    np.testing.assert_allclose(result["mean_ratio"], B.mean(axis=0) / A.mean(axis=0))
    assert set(METRICS) <= set(result)


def test_scale_invariance_of_relative_metrics():
    a, _ = disc_image()
    b = a * (1 + 0.1 * np.random.default_rng(2).normal(size=a.shape))
    base, scaled = compare(a, b), compare(1e3 * a, 1e3 * b)
    for name in ("relmse", "mean_rel_error", "mean_ratio"):
        np.testing.assert_allclose(scaled[name], base[name], rtol=1e-9)
    assert scaled["flip_mean"] == pytest.approx(base["flip_mean"], rel=1e-3)


def test_flip_grows_with_the_error():
    a, _ = disc_image()
    noise = np.random.default_rng(3).normal(size=a.shape)
    flips = [compare(a, np.clip(a * (1 + s * noise), 0, None))["flip_mean"] for s in (0.02, 0.1, 0.4)]
    assert 0 < flips[0] < flips[1] < flips[2] <= 1


def test_mask_restricts_the_pixels():
    a, inside = disc_image()
    b = a.copy()
    b[~inside] = 5.0  # background differences do not count
    assert compare(a, b)["rmse"] == [0.0, 0.0, 0.0]
    half = inside.copy()
    half[:, : a.shape[1] // 2] = False
    b[:, : a.shape[1] // 2] *= 2.0  # only the left half differs
    assert compare(a, b, mask=half)["rmse"] == [0.0, 0.0, 0.0]
    assert compare(a, b)["mean_rel_error"][0] == pytest.approx(0.5, abs=0.05)
    assert object_mask(a, half.astype(float)).sum() == half.sum()


def test_block_average_removes_noise_and_skips_the_silhouette():
    a, inside = disc_image(96, 128)
    smooth = np.where(inside[..., None], 0.5, 0.0) * np.ones(3)
    noisy = smooth * (1 + 0.3 * np.random.default_rng(4).normal(size=a.shape))
    errors = [compare(smooth, noisy, block=k)["mean_rel_error"][0] for k in (1, 2, 4, 8)]
    assert np.all(np.diff(errors) < 0)
    np.testing.assert_allclose(errors[0] / errors[-1], 8, rtol=0.3)  # noise falls as 1/k
    blocked = compare(smooth, smooth, block=4)
    assert blocked["rmse"] == [0.0, 0.0, 0.0] and blocked["mean_reference"] == [0.5, 0.5, 0.5]  # no background
    assert blocked["pixels"] == np.sum(block_average(inside, 4) == 1.0)


def test_block_average_shapes():
    image = np.arange(7 * 5 * 3, dtype=float).reshape(7, 5, 3)
    out = block_average(image, 2)
    assert out.shape == (3, 2, 3)
    np.testing.assert_allclose(out[1, 1], image[2:4, 2:4].mean(axis=(0, 1)))


def test_error_image_colours():
    a, inside = disc_image()
    b = a.copy()
    b[:, :32] *= 1.5
    b[:, 32:] *= 0.5
    image = error_image(a, b)
    assert image.shape == a.shape
    assert np.all(image[~inside] == 0)
    left, right = image[24, 20], image[24, 44]
    assert left[0] > left[2] and right[2] > right[0]  # red where brighter, blue where darker
    equal = error_image(a, a)[inside]
    assert np.all(equal == equal[0]) and np.all(equal[0] > 0.9)  # equal: white


@pytest.mark.parametrize("bad, message", [
    (dict(test=np.zeros((10, 10, 3))), "images differ in size: reference is 64x48 pixels, test is 10x10"),
    (dict(mask=np.ones((10, 10))), "mask is 10x10 pixels"),
    (dict(mask=np.zeros((48, 64))), "mask is empty"),
    (dict(block=0), "block=0"),
    (dict(block=100), "block=100 is larger"),
    (dict(block=40), "no 40x40 block lies wholly inside"),
])
def test_bad_input(bad, message):
    a, _ = disc_image()
    args = dict(reference=a, test=a) | bad
    with pytest.raises(ConvsssError, match=message):
        compare(**args)


def test_non_finite_object_pixels():
    a, inside = disc_image()
    b = a.copy()
    b[24, 32, 1] = np.nan
    with pytest.raises(ConvsssError, match="test has 1 object pixels with NaN"):
        compare(a, b)
    with pytest.raises(ConvsssError, match="zero everywhere"):
        compare(np.zeros_like(a), a)


@pytest.fixture
def exr_pair(tmp_path):
    a, inside = disc_image()
    paths = {"a": tmp_path / "a.exr", "b": tmp_path / "b.exr", "small": tmp_path / "small.exr",
             "mask": tmp_path / "mask.png"}
    write_exr(paths["a"], a)
    write_exr(paths["b"], 1.25 * a)
    write_exr(paths["small"], a[:20])
    write_png(paths["mask"], np.repeat(inside[..., None], 3, axis=2).astype(float), method="none")
    return paths


def test_cli_json(exr_pair, tmp_path):
    diff = tmp_path / "out" / "diff.png"
    result = run("compare", exr_pair["a"], exr_pair["b"], "--json", "-o", diff, "--mask", exr_pair["mask"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    for key in ("rmse", "relmse", "mean_rel_error", "mean_ratio"):
        assert len(report[key]) == 3
    np.testing.assert_allclose(report["mean_ratio"], 1.25, rtol=1e-5)  # float32 EXR
    assert 0 < report["flip_mean"] < 1 and report["size"] == [64, 48]
    assert report["error_image"] == str(diff) and read_image(diff).shape == (48, 64, 3)
    # A and B beside it, through one operator keyed on A: B = 1.25 A stays brighter (each keyed on itself, Reinhard
    # would show them alike).
    a_png, b_png = (read_image(p) for p in report["images"])
    assert report["images"] == [str(diff.with_name("diff-reference.png")), str(diff.with_name("diff-test.png"))]
    inside = read_image(exr_pair["mask"])[..., 0] > 0.5
    assert np.all(b_png[inside].mean(axis=0) > 1.1 * a_png[inside].mean(axis=0))


def test_cli_tonemapped_inputs_are_outputs_too(exr_pair, tmp_path):
    """-o diff.png also writes diff-reference.png and diff-test.png: they may not be inputs, and nothing is written
    when one is."""
    clash = tmp_path / "x-test.png"
    write_png(clash, np.ones((48, 64, 3)), method="none")
    before = clash.read_bytes()
    result = run("compare", exr_pair["a"], clash, "-o", tmp_path / "x.png")
    assert result.exit_code == 2 and "is an input of this command" in result.output
    assert clash.read_bytes() == before and not (tmp_path / "x.png").exists()
    assert not (tmp_path / "x-reference.png").exists()


def test_cli_table_and_block(exr_pair):
    result = run("compare", exr_pair["a"], exr_pair["b"], "--block", "2")
    assert result.exit_code == 0, result.output
    assert "mean B / mean A" in result.output and "FLIP mean" in result.output and "2x2 blocks" in result.output


def test_cli_mismatched_sizes_one_line(exr_pair):
    result = run("compare", exr_pair["a"], exr_pair["small"])
    assert result.exit_code == 2
    assert result.output.strip() == "error: images differ in size: a.exr is 64x48 pixels, small.exr is 64x20"


def test_cli_missing_file(exr_pair, tmp_path):
    result = run("compare", exr_pair["a"], tmp_path / "nope.exr")
    assert result.exit_code == 2 and "does not exist" in result.output


def test_mask_layer_prefers_mask_then_object_and_finds_nested_ones():
    ones = np.ones((2, 2, 1))
    assert mask_layer({"": ones}) is None and mask_layer({"exitance": ones}) is None
    assert mask_layer({"object": 0 * ones, "mask": ones})[0] == "mask"
    name, inside = mask_layer({"sss.object": np.array([[[0.0], [-0.1]], [[np.nan], [0.4]]])})
    assert name == "sss.object" and inside.tolist() == [[False, False], [False, True]]


@pytest.fixture
def floor_pair(tmp_path):
    """A disc on a lit floor (every pixel non-black), as a reference without AOVs and a test 1.25x as bright on the
    disc with the integrator's ``object`` and ``mask`` channels."""
    disc, inside = disc_image()
    floor = np.where(inside[..., None], disc, 0.3)
    test = np.where(inside[..., None], 1.25 * disc, 0.3)
    aovs = np.concatenate([test, inside[..., None] * [1.0, 1.0]], axis=2)
    paths = {"ref": tmp_path / "ref.exr", "test": tmp_path / "test.exr", "both": tmp_path / "both.exr"}
    write_exr(paths["ref"], floor)
    atomic_write(paths["test"], exr_writer(aovs, ["R", "G", "B", "object.I", "mask.Y"]))
    ring = inside & ~np.roll(inside, 3, axis=1)  # another mask in the reference: it comes first
    atomic_write(paths["both"], exr_writer(np.concatenate([floor, ring[..., None]], axis=2),
                                           ["R", "G", "B", "object.I"]))
    return paths, inside, ring


def test_cli_uses_a_mask_channel_and_says_so(floor_pair):
    """The test image's mask channel: only the disc's pixels compared (the scale is 1.25 there, the floor would pull it
    towards 1); without it (--no-mask-channels), every non-black pixel of the reference."""
    paths, inside, ring = floor_pair
    report = json.loads(run("compare", paths["ref"], paths["test"], "--json").output)
    assert report["pixels"] == inside.sum() < inside.size
    assert report["mask_source"] == {"kind": "channel", "image": str(paths["test"]), "channel": "mask"}
    assert report["mask"] is None
    np.testing.assert_allclose(report["mean_ratio"], 1.25, rtol=1e-5)
    report = json.loads(run("compare", paths["ref"], paths["test"], "--json", "--no-mask-channels").output)
    assert report["pixels"] == inside.size and report["mask_source"]["kind"] == "nonzero"
    report = json.loads(run("compare", paths["both"], paths["test"], "--json").output)
    assert report["pixels"] == ring.sum()  # the reference's own channel first
    assert report["mask_source"] == {"kind": "channel", "image": str(paths["both"]), "channel": "object"}
    table = run("compare", paths["ref"], paths["test"])
    assert table.exit_code == 0, table.output
    assert f"object pixels: the 'mask' channel of {paths['test']}" in table.output
    assert f"{inside.sum()} object pixels" in table.output


def test_cli_mask_image_overrides_the_channels(floor_pair, tmp_path):
    paths, inside, _ = floor_pair
    square = np.zeros(inside.shape + (3,))
    square[10:20, 10:20] = 1.0
    write_png(tmp_path / "square.png", square, method="none")
    report = json.loads(run("compare", paths["ref"], paths["test"], "--json", "--mask", tmp_path / "square.png").output)
    assert report["pixels"] == 100 and report["mask_source"]["kind"] == "image"


def test_cli_help_explains_every_option():
    text = run("compare", "--help").output
    for option in ("--mask", "--mask-channels", "--no-mask-channels", "--output", "--range", "--block", "--json",
                   "FLIP", "REFERENCE", "TEST"):
        assert option in text
