"""The render, reference and scene commands, run as a user would (CliRunner), on tiny images."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from convsss.cli import cli
from convsss.image import read_image


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    """A scene written by `convsss scene` (index-matched wholemilk bunny, volpathmis as its integrator)."""
    path = tmp_path_factory.mktemp("scene") / "milk.xml"
    result = run("scene", "--material", "wholemilk", "--size-mm", 20, "--boundary", "null", "--width", 40,
                 "--height", 32, "--spp", 2, "-o", path)
    assert result.exit_code == 0, result.output
    return path


def test_help_explains_every_option():
    for command in ("render", "reference", "scene"):
        result = run(command, "--help")
        assert result.exit_code == 0
        assert "--output" in result.output or command == "scene"
    text = run("render", "--help").output
    for option in ("--layers", "--threshold", "--downsample", "--spp", "--transport", "--width", "--height",
                   "--stats", "--tonemap", "--exposure", "--mesh", "--material", "--size-mm", "--floor"):
        assert option in text


def test_render_a_scene_made_for_volpathmis(scene_file, tmp_path):
    out = tmp_path / "out" / "milk"
    stats = tmp_path / "milk.json"
    result = run("render", scene_file, "-o", out, "--layers", 4, "--stats", stats, "--no-progress")
    assert result.exit_code == 0, result.output
    image = read_image(out.with_suffix(".exr"))
    assert image.shape == (32, 40, 3) and image.max() > 0
    assert out.with_suffix(".png").is_file()
    data = json.loads(stats.read_text())
    assert set(data["seconds"]) >= {"scene_load", "samples", "irradiance", "transport", "shading", "total"}
    assert data["parameters"]["layers"] == 4 and data["samples"] > 0
    transport = data["transports"][0]
    assert {"grid_shape", "fft_shape", "pairs_per_layer"} <= set(transport)
    assert len(data["objects"][0]["mean_free_paths"]) == 3 and len(data["objects"][0]["diffusion_lengths"]) == 3


def test_hand_written_volpath_scene_renders_as_it_is(tmp_path):
    """A scene written for volpathmis by hand (defaults, <lookat>, a referenced medium, an rgba film)."""
    scene = Path(__file__).parents[1] / "data" / "marble_cube_volpath.xml"
    out = tmp_path / "cube"
    result = run("render", scene, "-o", out, "--no-progress", "--irradiance-samples", 4)
    assert result.exit_code == 0, result.output
    image = read_image(out.with_suffix(".exr"))
    assert image.shape == (48, 48, 3) and np.all(np.isfinite(image)) and image.max() > 0


def test_quick_render_of_a_mesh(tmp_path):
    out = tmp_path / "bunny"
    result = run("render", "--mesh", "bunny", "--material", "skin1", "--size-mm", 30, "--floor", "--width", 32,
                 "--height", 24, "--spp", 1, "-o", out, "--no-progress", "--tonemap", "exposure")
    assert result.exit_code == 0, result.output
    assert read_image(out.with_suffix(".exr")).shape == (24, 32, 3)


def test_reference_saves_every_pass(scene_file, tmp_path):
    out = tmp_path / "ref"
    result = run("reference", scene_file, "-o", out, "--spp", 3, "--pass-spp", 2, "--no-progress")
    assert result.exit_code == 0, result.output
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["spp_done"] == 3 and info["passes_done"] == 2
    assert read_image(out.with_suffix(".exr")).max() > 0


def _scene_with(tmp_path, shape):
    path = tmp_path / "bad.xml"
    path.write_text(f"""<scene version="3.0.0">
    <sensor type="perspective"><transform name="to_world"><lookat origin="0,0,10" target="0,0,0" up="0,1,0"/>
    </transform><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
    <emitter type="point"><point name="position" value="0,5,5"/></emitter>
    {shape}
</scene>""")
    return path


BAD = {
    "no translucent shape": ('<shape type="sphere"/>', "no translucent shape"),
    "medium not homogeneous": ('<shape type="sphere"><bsdf type="null"/><medium type="heterogeneous" '
                               'name="interior"/></shape>', "only 'homogeneous'"),
    "eta below 1": ('<shape type="sphere"><bsdf type="dielectric"><float name="int_ior" value="1.0"/>'
                    '<float name="ext_ior" value="1.33"/></bsdf><medium type="homogeneous" name="interior"/>'
                    '</shape>', "must be >= 1"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scenes_fail_in_one_line_without_output(tmp_path, case):
    shape, message = BAD[case]
    out = tmp_path / "out"
    result = run("render", _scene_with(tmp_path, shape), "-o", out, "--stats", tmp_path / "s.json", "--no-progress")
    _assert_clean_failure(result, message, tmp_path)


@pytest.mark.parametrize("args, message", [
    (("--mesh", "bunny", "--material", "unobtainium", "--size-mm", 10), "unknown material 'unobtainium'"),
    (("--mesh", "/nonexistent/bunny.obj", "--material", "wholemilk", "--size-mm", 10), "does not exist"),
    (("--mesh", "bunny", "--material", "wholemilk"), "nothing to render"),
    (("--mesh", "bunny", "--material", "wholemilk", "--size-mm", 10, "--layers", 1), "layers=1"),
    (("/nonexistent/scene.xml",), "scene file '/nonexistent/scene.xml' does not exist"),
])
def test_bad_quick_input_fails_in_one_line_without_output(tmp_path, args, message):
    result = run("render", *args, "-o", tmp_path / "out", "--no-progress")
    _assert_clean_failure(result, message, tmp_path)


def _assert_clean_failure(result, message, folder):
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and message in lines[0], result.output
    assert "Traceback" not in result.output
    assert not [p for p in folder.rglob("*") if p.suffix in (".exr", ".png", ".json")]


def test_scene_command_prints_an_object_fragment():
    result = run("scene", "--material", "marble", "--size-mm", 50, "--object-only")
    assert result.exit_code == 0
    assert result.output.startswith('<shape type="obj" id="object">') and 'name="interior"' in result.output


def test_same_seed_same_png(scene_file, tmp_path):
    images = []
    for k in range(2):
        out = tmp_path / f"r{k}"
        assert run("render", scene_file, "-o", out, "--seed", 7, "--no-progress").exit_code == 0
        images.append(read_image(out.with_suffix(".png")))
    np.testing.assert_array_equal(*images)
