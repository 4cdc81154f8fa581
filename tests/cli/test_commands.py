"""The render, reference and scene commands, run as a user would (CliRunner), on tiny images."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from convsss.cli import cli
from convsss.image import read_image, read_layers
from convsss.profiles import model_profile


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def _src_path():
    """The ``src`` folder this ``convsss`` was imported from, for a subprocess to import the same one."""
    import convsss

    return str(Path(convsss.__file__).parents[1])


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
                   "--stats", "--tonemap", "--exposure", "--mesh", "--material", "--size-mm", "--floor", "--aovs",
                   "--mask", "exitance", "irradiance"):
        assert option in text


@pytest.mark.slow
def test_render_a_scene_made_for_volpathmis(scene_file, tmp_path):
    out = tmp_path / "out" / "milk"
    stats = tmp_path / "milk.json"
    result = run("render", scene_file, "-o", out, "--transport", "convolution", "--layers", 4, "--stats", stats,
                 "--no-progress")
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


@pytest.mark.slow
def test_hand_written_volpath_scene_renders_as_it_is(tmp_path):
    """A scene written for volpathmis by hand (defaults, <lookat>, a referenced medium, an rgba film)."""
    scene = Path(__file__).parents[1] / "data" / "marble_cube_volpath.xml"
    out = tmp_path / "cube-0.5"  # a dot in the stem is kept: cube-0.5.exr, not cube-0.exr
    result = run("render", scene, "-o", out, "--no-progress", "--irradiance-samples", 4)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cube-0.5.exr", "cube-0.5.png"]
    image = read_image(tmp_path / "cube-0.5.exr")
    assert image.shape == (48, 48, 3) and np.all(np.isfinite(image)) and image.max() > 0


@pytest.mark.slow
def test_quick_render_of_a_mesh(tmp_path):
    out = tmp_path / "bunny"
    result = run("render", "--mesh", "bunny", "--material", "skin1", "--size-mm", 30, "--floor", "--width", 32,
                 "--height", 24, "--spp", 1, "-o", out, "--no-progress", "--tonemap", "exposure")
    assert result.exit_code == 0, result.output
    assert read_image(out.with_suffix(".exr")).shape == (24, 32, 3)


@pytest.mark.slow
def test_aovs_and_mask_land_in_the_exr_and_a_png_and_compare_uses_them(tmp_path):
    """--aovs: channels of OUT.exr; --mask: the mask AOV too, and OUT-mask.png; compare then takes the bunny's
    pixels, not the lit floor's."""
    out, stats = tmp_path / "bunny", tmp_path / "bunny.json"
    result = run("render", "--mesh", "bunny", "--material", "skin1", "--size-mm", 30, "--floor", "--width", 32,
                 "--height", 24, "--spp", 2, "-o", out, "--no-progress", "--aovs", "exitance,object", "--mask",
                 "--stats", stats)
    assert result.exit_code == 0, result.output
    mask_png = tmp_path / "bunny-mask.png"
    assert str(mask_png) in result.output
    layers = read_layers(out.with_suffix(".exr"))
    assert sorted(layers) == ["", "exitance", "mask", "object"]
    assert layers[""].shape == (24, 32, 3) and layers["exitance"].shape == (24, 32, 3)
    mask = layers["mask"][..., 0]
    np.testing.assert_array_equal(layers["object"][..., 0] > 0, mask > 0)  # one object: index 1
    np.testing.assert_allclose(read_image(mask_png)[..., 0], mask, atol=0.005)
    lit = np.any(layers[""] > 0, axis=-1)
    assert 20 < np.count_nonzero(mask) < 0.5 * np.count_nonzero(lit)
    data = json.loads(stats.read_text())
    assert data["aovs"] == ["exitance.R", "exitance.G", "exitance.B", "object.I", "mask.Y"]
    assert data["outputs"]["mask"] == str(mask_png) and data["parameters"]["aovs"] == "exitance,object,mask"
    result = run("compare", out.with_suffix(".exr"), out.with_suffix(".exr"), "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert report["pixels"] == np.count_nonzero(mask) and report["mask_source"]["channel"] == "mask"


@pytest.mark.slow
def test_mask_keeps_the_scenes_own_aovs(studio):
    text = re.sub(r'<integrator type="volpathmis">.*?</integrator>', '<integrator type="convsss"><string '
                  'name="aovs" value="depth"/></integrator>', (studio / "studio.xml").read_text(), flags=re.DOTALL)
    (studio / "aovs.xml").write_text(text)
    result = run("render", "aovs.xml", "-o", "out", "--mask", "--no-progress", "--irradiance-samples", 2)
    assert result.exit_code == 0, result.output
    assert sorted(read_layers(studio / "out.exr")) == ["", "depth", "mask"]
    assert (studio / "out-mask.png").is_file()


@pytest.mark.parametrize("aovs, message", [
    ("position", "aovs='position' is not allowed: 'position' is not an AOV of convsss; choose from exitance, "
                 "irradiance, object, mask, depth, normal, albedo"),
    ("depth,depth", "aovs='depth,depth' is not allowed: 'depth' is named twice"),
])
def test_bad_aovs_fail_in_one_line(studio, aovs, message):
    before = _snapshot(studio)
    _assert_refused(run("render", "studio.xml", "-o", "out", "--aovs", aovs, "--mask", "--no-progress"), message,
                    studio, before)


@pytest.mark.slow
def test_reference_saves_every_pass(scene_file, tmp_path):
    out = tmp_path / "ref"
    result = run("reference", scene_file, "-o", out, "--spp", 3, "--pass-spp", 2, "--no-progress")
    assert result.exit_code == 0, result.output
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["spp_done"] == 3 and info["passes_done"] == 2
    assert read_image(out.with_suffix(".exr")).max() > 0


@pytest.mark.slow
def test_exposure_from_keys_the_png_on_another_image(scene_file, tmp_path):
    """--exposure-from IMAGE: the PNG keyed on IMAGE (here a reference 4x as bright: darker than keyed on itself);
    the EXR unchanged."""
    from convsss.image import write_exr, write_png

    ref = tmp_path / "ref"
    assert run("reference", scene_file, "-o", ref, "--spp", 1, "--pass-spp", 1, "--no-progress").exit_code == 0
    linear = read_image(ref.with_suffix(".exr"))
    write_exr(tmp_path / "bright.exr", 4.0 * linear)
    dim = tmp_path / "dim"
    result = run("reference", scene_file, "-o", dim, "--spp", 1, "--pass-spp", 1, "--no-progress",
                 "--exposure-from", tmp_path / "bright.exr")
    assert result.exit_code == 0, result.output
    np.testing.assert_allclose(read_image(dim.with_suffix(".exr")), linear, rtol=1e-5)  # same seed (up to 1e-7)
    png, own = read_image(dim.with_suffix(".png")), read_image(ref.with_suffix(".png"))
    assert png.mean() < 0.7 * own.mean()
    expected = read_image(write_png(tmp_path / "expected-dim.png", linear, anchor=4.0 * linear))
    np.testing.assert_allclose(png, expected, atol=0.01)  # the EXR is float32, the PNG made from float64
    out = tmp_path / "conv"
    result = run("render", scene_file, "-o", out, "--no-progress", "--exposure-from", ref.with_suffix(".exr"),
                 "--stats", tmp_path / "conv.json")
    assert result.exit_code == 0, result.output
    expected = read_image(write_png(tmp_path / "expected-conv.png", read_image(out.with_suffix(".exr")),
                                    anchor=linear))
    np.testing.assert_allclose(read_image(out.with_suffix(".png")), expected, atol=0.01)
    assert not np.allclose(read_image(out.with_suffix(".png")),
                           read_image(write_png(tmp_path / "own.png", read_image(out.with_suffix(".exr")))), atol=0.01)
    assert json.loads((tmp_path / "conv.json").read_text())["tonemap"]["exposure_from"] == str(ref) + ".exr"


@pytest.mark.slow
def test_reference_of_a_black_scene_warns_or_fails_with_strict(tmp_path):
    """Point lights behind a smooth dielectric: volpathmis renders the object black. A warning, or with --strict
    exit code 1, one line and nothing written."""
    dark = tmp_path / "dark.xml"
    assert run("scene", "--material", "skin1", "--size-mm", 4, "--boundary", "dielectric", "--width", 12,
               "--height", 8, "--spp", 1, "-o", dark).exit_code == 0
    result = run("reference", dark, "-o", tmp_path / "strict", "--strict", "--no-progress")
    assert result.exit_code == 1, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: volpathmis pass 1 of 1 is black"), result.stderr
    assert "Traceback" not in result.output and not list(tmp_path.glob("strict*"))
    result = run("reference", dark, "-o", tmp_path / "loose", "--no-progress")
    assert result.exit_code == 0 and "warning: volpathmis pass 1 of 1 is black" in result.stderr
    assert read_image(tmp_path / "loose.exr").max() == 0


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
    "volume not covering": ('<shape type="sphere"><bsdf type="null"/><medium type="heterogeneous" '
                            'name="interior"/></shape>', "does not cover the object"),
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
    """Printed, the fragment names the mesh by its absolute path (no folder to be relative to) and takes its id from
    the mesh's name."""
    from convsss.scene.quick import demo_mesh

    result = run("scene", "--material", "marble", "--size-mm", 50, "--object-only")
    assert result.exit_code == 0
    assert result.output.startswith('<shape type="obj" id="bunny">') and 'name="interior"' in result.output
    assert f'<string name="filename" value="{demo_mesh().resolve()}"/>' in result.output


def test_scene_file_names_its_mesh_relative_to_itself(tmp_path, monkeypatch):
    """-o scenes/drop.xml with meshes/milk-drop.obj: the file says ../meshes/milk-drop.obj and id "milk-drop", and
    loads from any working directory (Mitsuba resolves against the scene's folder)."""
    import shutil

    from convsss.scene.loading import load_scene, scene_inputs
    from convsss.scene.quick import demo_mesh

    (tmp_path / "meshes").mkdir()
    mesh = tmp_path / "meshes" / "milk-drop.obj"
    shutil.copy(demo_mesh(), mesh)
    out = tmp_path / "scenes" / "drop.xml"
    fragment = tmp_path / "scenes" / "drop-object.xml"
    assert run("scene", "--mesh", mesh, "--material", "wholemilk", "--size-mm", 10, "--width", 8, "--height", 8,
               "-o", out).exit_code == 0
    assert run("scene", "--mesh", mesh, "--material", "wholemilk", "--size-mm", 10, "--object-only",
               "-o", fragment).exit_code == 0
    for text in (out.read_text(), fragment.read_text()):
        assert '<string name="filename" value="../meshes/milk-drop.obj"/>' in text and 'id="milk-drop"' in text
    monkeypatch.chdir(tmp_path / "meshes")
    assert mesh.resolve() in [p.resolve() for p in scene_inputs(out)]  # an output may never overwrite it
    scene = load_scene(out)
    assert [s.id() for s in scene.shapes()] == ["milk-drop"]


@pytest.mark.parametrize("args, expected", [
    (("--id", "cup"), 'id="cup"'),
    (("--mesh", "3d scan.obj"), 'id="mesh_3d_scan"'),
])
def test_scene_object_id_is_given_or_made_valid(tmp_path, args, expected):
    from convsss.scene.quick import demo_mesh

    if "--mesh" in args:
        (tmp_path / args[1]).write_bytes(demo_mesh().read_bytes())
        args = ("--mesh", tmp_path / args[1])
    result = run("scene", "--material", "marble", "--size-mm", 50, "--object-only", *args)
    assert result.exit_code == 0, result.output
    assert expected in result.output.splitlines()[0]


@pytest.mark.parametrize("shape_id, message", [
    ("2 cups", "--id '2 cups' is not allowed: an id is a letter or _ followed by letters, digits, _ or -"),
    ("key_light", "--id 'key_light' is taken by the scene's key light"),
])
def test_bad_scene_ids_fail_in_one_line(tmp_path, shape_id, message):
    result = run("scene", "--material", "marble", "--size-mm", 50, "--id", shape_id, "-o", tmp_path / "s.xml")
    _assert_refused(result, message)
    assert not (tmp_path / "s.xml").exists()


@pytest.mark.slow
def test_same_seed_same_png(scene_file, tmp_path):
    images = []
    for k in range(2):
        out = tmp_path / f"r{k}"
        assert run("render", scene_file, "-o", out, "--seed", 7, "--no-progress").exit_code == 0
        images.append(read_image(out.with_suffix(".png")))
    np.testing.assert_array_equal(*images)


# ---- Inputs are sacred, one-line errors, outputs together or not at all ----------------------------------------------
def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() if p.is_file() else None for p in folder.rglob("*")}


def _assert_refused(result, message, folder=None, before=None):
    """Exit code 2, one line on stderr (``error: ...`` with ``message``), no traceback, every file as it was."""
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.stderr
    assert "Traceback" not in result.output
    if folder is not None:
        assert _snapshot(folder) == before


@pytest.fixture
def studio(scene_file, tmp_path, monkeypatch):
    """A folder (the working directory) with studio.xml: the test scene plus an environment map studio.exr named in
    an included lights.xml; also a profile skin.csv and a mesh bunny.obj."""
    from convsss.image import write_exr

    write_exr(tmp_path / "studio.exr", np.full((4, 8, 3), 0.05))
    (tmp_path / "lights.xml").write_text('<scene version="3.0.0"><emitter type="envmap">'
                                         '<string name="filename" value="studio.exr"/></emitter></scene>')
    (tmp_path / "studio.xml").write_text(
        scene_file.read_text().replace("</scene>", '<include filename="lights.xml"/></scene>'))
    (tmp_path / "skin.csv").write_text("r_mm,R,G,B\n0,1,1,1\n1,0.5,0.5,0.5\n")
    (tmp_path / "bunny.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


QUICK = ("--mesh", "bunny.obj", "--material", "wholemilk", "--size-mm", 10)


@pytest.mark.parametrize("args", [
    ("render", "studio.xml", "-o", "studio"),
    ("render", "studio.xml", "-o", "out.png", "--stats", "studio.xml"),
    ("render", "studio.xml", "-o", "out", "--stats", "./lights.xml"),
    ("render", "studio.xml", "-o", "out", "--profile", "skin.csv", "--stats", "skin.csv"),
    ("render", *QUICK, "-o", "out", "--stats", "bunny.obj"),
    ("reference", "studio.xml", "-o", "studio.exr"),
    ("reference", "studio.xml", "-o", "ref", "--exposure-from", "ref.exr"),
    ("render", "studio.xml", "-o", "out", "--exposure-from", "out.exr"),
    ("scene", *QUICK, "-o", "bunny.obj"),
])
def test_outputs_never_overwrite_inputs(studio, args):
    before = _snapshot(studio)
    result = run(*args, *(("--no-progress",) if args[0] != "scene" else ()))
    _assert_refused(result, "is an input of this command", studio, before)


@pytest.mark.parametrize("args, message", [
    (("render", "-o", "/proc/x/img"), "cannot write into '/proc/x'"),
    (("render", "-o", "studio.xml/img"), "not a folder"),
    (("render", "-o", "out", "--stats", "/proc/x/stats.json"), "cannot write into '/proc/x'"),
    (("render", "-o", "out", "--stats", "out.exr"), "named twice"),
    (("render", "-o", "out", "--mask", "--stats", "out-mask.png"), "named twice"),
    (("render", "-o", "taken", "--mask"), "'taken-mask.png' is a folder"),
    (("render", "-o", "taken"), "'taken.png' is a folder"),
    (("reference", "-o", "/proc/x/img"), "cannot write into '/proc/x'"),
    (("reference", "-o", "studio.xml/img"), "not a folder"),
    (("reference", "-o", "taken"), "'taken.png' is a folder"),
])
def test_unwritable_outputs_fail_before_the_render(studio, args, message):
    (studio / ("taken-mask.png" if "--mask" in args else "taken.png")).mkdir()
    before = _snapshot(studio)
    _assert_refused(run(args[0], "studio.xml", *args[1:], "--no-progress"), message, studio, before)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder_fails_before_the_render(studio):
    (studio / "ro").mkdir(mode=0o555)
    _assert_refused(run("render", "studio.xml", "-o", "ro/img", "--no-progress"), "cannot write into 'ro'")


@pytest.mark.parametrize("args, message", [
    (("--seed", -5), "Invalid value for '--seed': -5 is not in the range 0<=x<=4294967295"),
    (("--spp", 0), "Invalid value for '--spp'"),
    (("--spp", -3), "Invalid value for '--spp'"),
    (("--seed", "1e23"), "Invalid value for '--seed'"),
    (("--seed", 2**32), "Invalid value for '--seed'"),
    (("--exposure", "nan"), "exposure=nan is not allowed"),
    (("--exposure", "1e9"), "exposure=1000000000.0 is not allowed"),
    (("--accuracy", "1e-300"), "accuracy"),
    (("--key", 0), "key=0.0 is not allowed"),
    (("--key", -1), "key=-1.0 is not allowed"),
    (("--exposure-from", "nope.exr"), "image 'nope.exr' does not exist"),
    (("--exposure-from", "studio.exr", "--tonemap", "exposure"), "it needs --tonemap reinhard, not exposure"),
])
@pytest.mark.parametrize("command", ["render", "reference"])
def test_bad_option_values_fail_in_one_line(studio, command, args, message):
    before = _snapshot(studio)
    _assert_refused(run(command, "studio.xml", "-o", "out", *args, "--no-progress"), message, studio, before)


@pytest.mark.parametrize("profile, message", [
    ("studio.exr", "profile file 'studio.exr' is not a CSV"),
    ("three.csv", "profile file 'three.csv' line 2 has 3 columns: a profile needs 4 columns r_mm, R, G, B"),
])
def test_bad_profile_files_fail_in_one_line(studio, profile, message):
    (studio / "three.csv").write_text("r_mm,R,G,B\n0,1,1\n1,0.5,0.5\n")
    before = _snapshot(studio)
    _assert_refused(run("render", "studio.xml", "-o", "out", "--profile", profile, "--no-progress"), message, studio,
                    before)


def test_a_bad_integrator_parameter_in_the_scene_is_one_line(studio):
    (studio / "layers.xml").write_text((studio / "studio.xml").read_text().replace(
        "<scene version=\"3.0.0\">", '<scene version="3.0.0"><integrator type="convsss">'
                                     '<integer name="layers" value="0"/></integrator>'))
    before = _snapshot(studio)
    result = run("render", "layers.xml", "-o", "out", "--no-progress")
    _assert_refused(result, "layers=0", studio, before)
    assert result.stderr.strip() == "error: layers=0 is not allowed: it must be a whole number >= 2 and <= 256"


@pytest.mark.slow
def test_the_largest_seed_renders_a_reference(scene_file, tmp_path):
    result = run("reference", scene_file, "-o", tmp_path / "ref", "--seed", 2**32 - 1, "--spp", 2, "--pass-spp", 1,
                 "--no-progress")
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "ref.json").read_text())["seed"] == 2**32 - 1


def test_reference_warns_of_an_open_mesh_as_render_does(tmp_path):
    """Issue 51: `render` warned that a translucent mesh is not watertight, `reference` said nothing."""
    vertices = "".join(f"v {x} {y} {z}\n" for x in (0, 1) for y in (0, 1) for z in (0, 1))
    faces = ["1 2 4 3", "5 7 8 6", "1 5 6 2", "3 4 8 7", "1 3 7 5"]  # a cube without its sixth face
    (tmp_path / "open.obj").write_text(vertices + "".join(f"f {f}\n" for f in faces))
    for command in ("render", "reference"):
        result = run(command, "--mesh", tmp_path / "open.obj", "--material", "wholemilk", "--size-mm", 10, "--width",
                     8, "--height", 8, "--spp", 1, "-o", tmp_path / command, "--no-progress")
        assert result.exit_code == 0, result.output
        assert "translucent mesh 'object' is not watertight" in result.stderr, (command, result.stderr)
    # Issue 62: behind an open surface, nothing closing it, volpathmis's paths without Russian roulette wandered for
    # minutes (an open marble triangle, 128 spp); the reference says it turns the roulette on, and records it.
    assert "Russian roulette is on from depth 5" in result.stderr
    assert json.loads((tmp_path / "reference.json").read_text())["rr_depth"] == 5


@pytest.mark.slow
def test_reference_ends_on_an_object_far_thinner_than_a_mean_free_path(tmp_path):
    """Issue 51: `reference` on a 1e-6 mm object had never ended (paths without Russian roulette that never leave
    the medium); it ends in about a second."""
    done = subprocess.run([sys.executable, "-m", "convsss", "reference", "--mesh", "bunny", "--material", "wholemilk",
                           "--size-mm", "1e-6", "--width", "8", "--height", "8", "--spp", "1", "-o",
                           str(tmp_path / "tiny"), "--no-progress"], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": _src_path()})
    assert done.returncode == 0 and (tmp_path / "tiny.exr").is_file(), done.stderr


def _interrupt(args, tmp_path, shown, wait=0.0, sig=signal.SIGINT, python=("-m", "convsss")):
    """Run ``convsss ARGS`` (``python ARGS``), send SIGINT (or ``sig``: SIGTERM) once stderr shows ``shown`` (and
    ``wait`` seconds more): exit code 130 (143), ``interrupted`` (``terminated``), no traceback and no file written."""
    proc = subprocess.Popen([sys.executable, *python, *args], stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": _src_path()})
    started = ""
    while shown not in started:
        char = proc.stderr.read(1)
        assert char, f"the command ended before {shown!r}: {started}"
        started += char
    time.sleep(wait)
    proc.send_signal(sig)
    try:  # communicate, not wait: the progress bar keeps writing, and a full pipe would block the command
        rest = proc.communicate(timeout=60)[1]
    finally:
        proc.kill()
    code, stderr = proc.returncode, started + rest
    expected = (130, "interrupted") if sig == signal.SIGINT else (143, "terminated")
    assert code == expected[0], stderr
    assert "Traceback" not in stderr and stderr.rstrip().endswith(expected[1])
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]


@pytest.mark.slow
def test_ctrl_c_ends_reference_in_one_line_without_outputs(scene_file, tmp_path):
    """SIGINT during the first pass (the progress bar shows once the scene is loaded, just before it)."""
    _interrupt(["reference", str(scene_file), "-o", str(tmp_path / "out" / "ref"), "--width", "16", "--height", "16",
                "--spp", "1000000", "--pass-spp", "4000"], tmp_path, "volpathmis", wait=0.3)


@pytest.mark.slow
@pytest.mark.parametrize("stage", ["transport", "shading"])
def test_ctrl_c_ends_render_in_one_line_without_outputs(tmp_path, stage):
    """SIGINT once the progress bar shows ``stage``."""
    # The exact sum's time grows with the samples: the pixel rule's 20 000 (--profile-samples 0) keep it seconds.
    _interrupt(["render", "--mesh", "bunny", "--material", "wholemilk", "--size-mm", "40", "--width", "96",
                "--height", "96", "--spp", "256", "-o", str(tmp_path / "out" / "img"), "--transport", "exact",
                "--profile-samples", "0"], tmp_path, stage)


_BUNNY = ["--mesh", "bunny", "--material", "wholemilk", "--size-mm", "40", "--width", "96", "--height", "96"]


@pytest.mark.slow
@pytest.mark.parametrize("options, shown", [
    (["--spp", "64", "--passes", "8"], "pass 2/8"),  # between passes (issue 51: it ran to the end, exit 0)
    (["--spp", "256", "--transport", "volume"], "transport"),  # inside the volume's solve (the same)
])
def test_ctrl_c_ends_a_render_in_passes_or_in_the_volume(tmp_path, options, shown):
    _interrupt(["render", *_BUNNY, *options, "-o", str(tmp_path / "out" / "img")], tmp_path, shown)


@pytest.mark.slow
def test_ctrl_c_at_the_write_stage_writes_nothing(tmp_path):
    """Issue 51: a Ctrl-C at the write stage exited 0 with the outputs written. The writers are slowed here (each
    file waits 30 s once written to its temporary), so that the signal lands while the first file is written."""
    slowed = ("import time, convsss.outputs as outputs\n"
              "write_files = outputs.write_files\n"
              "def slowed(write):\n"
              "    return lambda tmp: (write(tmp), time.sleep(30))\n"
              "outputs.write_files = lambda writers: write_files({p: slowed(w) for p, w in writers.items()})\n"
              "from convsss.cli import main\n"
              "main()\n")
    _interrupt(["render", *_BUNNY, "--spp", "4", "-o", str(tmp_path / "out" / "img")], tmp_path, "write", wait=1.0,
               python=("-c", slowed))


@pytest.mark.slow
def test_ctrl_c_ends_a_fit(scene_file, tmp_path_factory, tmp_path):
    """Issue 51: a fit once ran on 60 s after Ctrl-C, once to its end with its outputs written and exit 0."""
    target = tmp_path_factory.mktemp("target") / "skin"
    result = run("render", "--mesh", "bunny", "--material", "skin1", "--size-mm", 20, "--boundary", "null",
                 "--width", 40, "--height", 32, "--spp", 2, "-o", target, "--no-progress")
    assert result.exit_code == 0, result.output
    _interrupt(["fit", str(scene_file), f"{target}.exr", "-o", str(tmp_path / "out" / "fitted"), "--spp", "2",
                "--max-evaluations", "200"], tmp_path, "fit: evaluation")


@pytest.mark.slow
def test_ctrl_c_ends_a_render_of_long_walks(tmp_path):
    """SIGINT during random walks to their end in a 100 mm marble bunny, a render of minutes in one kernel: the walks
    run in chunks of camera paths, so it stops within the 60 s _interrupt waits (it took 50 s in one kernel)."""
    _interrupt(["render", "--mesh", "bunny", "--material", "marble", "--size-mm", "100", "--boundary", "null",
                "--width", "200", "--height", "200", "--spp", "2048", "--walk-depth", "inf",
                "-o", str(tmp_path / "out" / "img")], tmp_path, "shading", wait=3.0)


@pytest.mark.slow
def test_sigterm_ends_render_as_ctrl_c_does(tmp_path):
    """SIGTERM once the shading starts (issue 30, defect 7: it had left hidden temporaries and exit 143 without a
    word): one line, exit 143, no file."""
    _interrupt(["render", "--mesh", "bunny", "--material", "wholemilk", "--size-mm", "40", "--width", "96",
                "--height", "96", "--spp", "256", "-o", str(tmp_path / "out" / "img"), "--transport", "exact",
                "--profile-samples", "0"], tmp_path, "shading", sig=signal.SIGTERM)


# ---- Materials by colour and distance, presets named in scene files ------------------------------------------

@pytest.mark.slow
def test_render_reference_and_scene_take_a_colour_and_mfp(tmp_path):
    """--color/--mfp-mm instead of --material: the object's material is material_from_color's (under the default
    model at the boundary's eta), in render's stats, in the scene written and in reference."""
    import convsss
    from convsss.pipeline.objects import find_translucent_objects
    from convsss.scene.loading import load_scene

    colour = ("--color", "0.8,0.5,0.3", "--mfp-mm", "1,2,3")
    expected = convsss.material_from_color([0.8, 0.5, 0.3], [1, 2, 3], eta=1.4)
    stats = tmp_path / "r.json"
    result = run("render", "--mesh", "bunny", *colour, "--eta", 1.4, "--size-mm", 20, "--width", 32, "--height", 24,
                 "--spp", 1, "-o", tmp_path / "r", "--stats", stats, "--no-progress")
    assert result.exit_code == 0, result.output
    obj = json.loads(stats.read_text())["objects"][0]
    np.testing.assert_allclose(obj["sigma_s_prime_per_mm"], expected.sigma_s_prime, rtol=1e-5)
    np.testing.assert_allclose(obj["sigma_a_per_mm"], expected.sigma_a, rtol=1e-5)
    assert obj["eta"] == pytest.approx(1.4)

    out = tmp_path / "colour.xml"
    result = run("scene", *colour, "--color-model", "pbd", "--boundary", "null", "--size-mm", 20, "--width", 16,
                 "--height", 16, "--spp", 1, "-o", out)
    assert result.exit_code == 0, result.output
    assert '<medium type="homogeneous"' in out.read_text()  # plain Mitsuba loads it
    made = find_translucent_objects(convsss.register(), load_scene(out))[0].material
    np.testing.assert_allclose(model_profile("pbd", made).total_reflectance, [0.8, 0.5, 0.3], atol=1e-3)
    np.testing.assert_allclose(made.mfp_mm, [1, 2, 3], rtol=1e-5)
    assert made.eta == 1.0  # a null boundary is index-matched: the colour is inverted at eta 1

    result = run("reference", "--mesh", "bunny", *colour, "--boundary", "null", "--size-mm", 20, "--width", 16,
                 "--height", 16, "--spp", 1, "-o", tmp_path / "ref", "--no-progress")
    assert result.exit_code == 0, result.output
    assert read_image(tmp_path / "ref.exr").max() > 0


@pytest.mark.slow
def test_render_warns_when_the_colour_model_is_not_the_rendered_one(tmp_path):
    args = ("render", "--mesh", "bunny", "--color", "0.7", "--mfp-mm", "1", "--size-mm", 20, "--width", 16,
            "--height", 16, "--spp", 1, "--no-progress", "--transport", "hierarchical")
    result = run(*args, "--profile", "better-dipole", "--profile-total", "model", "-o", tmp_path / "a")
    assert result.exit_code == 0, result.output
    assert "warning: --color is the exact total reflectance but the object renders with the better-dipole total: " \
           "give --color-model better-dipole" in result.stderr
    result = run(*args, "--profile", "better-dipole", "--profile-total", "model", "--color-model", "better-dipole",
                 "-o", tmp_path / "b")
    assert result.exit_code == 0 and "--color-model" not in result.stderr
    result = run(*args, "--profile", "better-dipole", "-o", tmp_path / "c")  # every model renders the exact total
    assert result.exit_code == 0 and "--color-model" not in result.stderr


@pytest.mark.parametrize("args, message", [
    (("--mesh", "bunny", "--material", "skin1", "--color", "0.5", "--mfp-mm", "1", "--size-mm", 10),
     "give --material or --color/--mfp-mm, not both"),
    (("--mesh", "bunny", "--color", "0.5", "--size-mm", 10), "--color needs --mfp-mm"),
    (("--mesh", "bunny", "--mfp-mm", "1", "--size-mm", 10), "--mfp-mm needs --color"),
    (("--mesh", "bunny", "--color", "1.2,0.5,0.3", "--mfp-mm", "1", "--size-mm", 10),
     "colour 1.2 in channel R is not reachable by the exact total"),
    (("--mesh", "bunny", "--color", "0.5,-0.1,0.3", "--mfp-mm", "1", "--size-mm", 10), "channel G is not reachable"),
    (("--mesh", "bunny", "--color", "0.5", "--mfp-mm", "0", "--size-mm", 10), "must be finite and > 0"),
    (("--mesh", "bunny", "--color", "0.5,0.4", "--mfp-mm", "1", "--size-mm", 10), "give one number or three"),
    (("--mesh", "bunny", "--color", "0.5", "--mfp-mm", "1", "--eta", 1.4, "--boundary", "null", "--size-mm", 10),
     "--eta 1.4 is not allowed with --boundary null"),
    (("--mesh", "bunny", "--material", "skin1", "--eta", 1.4, "--size-mm", 10), "--eta goes with --color"),
    (("--mesh", "bunny", "--size-mm", 10), "nothing to render"),
])
@pytest.mark.parametrize("command", ["render", "reference"])
def test_bad_colour_input_fails_in_one_line_without_output(tmp_path, command, args, message):
    result = run(command, *args, "-o", tmp_path / "out", "--no-progress")
    _assert_clean_failure(result, message, tmp_path)


def test_scene_refuses_a_bad_colour_in_one_line(tmp_path):
    result = run("scene", "--color", "0.5", "--mfp-mm", "-1", "--size-mm", 10, "-o", tmp_path / "s.xml")
    _assert_refused(result, "mfp_mm=[-1.0, -1.0, -1.0] is not allowed")
    _assert_refused(run("scene", "--size-mm", 10), "no material: give --material NAME, or --color and --mfp-mm")
    assert not (tmp_path / "s.xml").exists()


NAMED_BAD = {
    "unknown preset": ('<string name="preset" value="wholemlk"/>',
                       "convsss_medium: unknown material 'wholemlk'; did you mean 'Wholemilk'"),
    "preset and coefficients": ('<string name="preset" value="skin1"/><rgb name="sigma_t" value="1"/>',
                                "a preset and coefficients (sigma_t) given"),
    "preset and colour": ('<string name="preset" value="skin1"/><rgb name="color" value="0.5"/>'
                          '<float name="mfp_mm" value="1"/>', "both a preset and color/mfp_mm"),
    "colour above 1": ('<rgb name="color" value="0.5, 1.5, 0.5"/><float name="mfp_mm" value="1"/>',
                       "colour 1.5 in channel G is not reachable"),
    "mfp 0": ('<rgb name="color" value="0.5"/><float name="mfp_mm" value="0"/>', "must be finite and > 0"),
    "eta of the boundary": ('<string name="preset" value="skin1"/>', "has eta 1.3, but its dielectric boundary"),
}


@pytest.mark.parametrize("command", ["render", "reference"])
@pytest.mark.parametrize("case", sorted(NAMED_BAD))
def test_bad_named_media_fail_in_one_line_without_output(tmp_path, command, case):
    medium, message = NAMED_BAD[case]
    bsdf = '<bsdf type="dielectric"/>' if case == "eta of the boundary" else '<bsdf type="null"/>'
    path = _scene_with(tmp_path, f'<shape type="sphere">{bsdf}<medium type="convsss_medium" name="interior">'
                                 f'{medium}</medium></shape>')
    result = run(command, path, "-o", tmp_path / "out", "--no-progress")
    _assert_clean_failure(result, message, tmp_path)


@pytest.mark.slow
def test_the_example_scene_renders_with_convsss_and_volpathmis(tmp_path):
    example = Path(__file__).parents[2] / "examples" / "skin_preset.xml"
    for command in ("render", "reference"):
        out = tmp_path / command
        result = run(command, example, "-o", out, "--width", 40, "--height", 30, "--spp", 2, "--no-progress")
        assert result.exit_code == 0, result.output
        assert read_image(out.with_suffix(".exr")).max() > 0


# ---- Sensors, ports and names (issue 30: friction and defect 10) -----------------------------------------------

@pytest.fixture(scope="module")
def two_sensors(scene_file, tmp_path_factory):
    """The test scene with a second camera, 16 x 8, looking from the other side."""
    text = scene_file.read_text()
    start = text.index("<sensor")
    sensor = text[start:text.index("</sensor>") + len("</sensor>")]
    second = re.sub(r'name="width" value="\d+"', 'name="width" value="16"', sensor)
    second = re.sub(r'name="height" value="\d+"', 'name="height" value="8"', second)
    path = tmp_path_factory.mktemp("sensors") / "two.xml"
    path.write_text(text.replace(sensor, sensor + second))
    return path


@pytest.mark.slow
def test_sensor_picks_a_camera_and_the_first_is_named(two_sensors, tmp_path):
    result = run("render", two_sensors, "-o", tmp_path / "a", "--spp", 1, "--no-progress", "--stats",
                 tmp_path / "a.json")
    assert result.exit_code == 0, result.output
    assert "the scene has 2 sensors; rendering sensor 0 (--sensor picks another)" in result.output
    result = run("render", two_sensors, "-o", tmp_path / "b", "--spp", 1, "--no-progress", "--sensor", 1)
    assert result.exit_code == 0, result.output
    from convsss.image import read_image

    assert read_image(tmp_path / "b.exr").shape[:2] == (8, 16) != read_image(tmp_path / "a.exr").shape[:2]
    assert json.loads((tmp_path / "a.json").read_text())["sensor"] == 0
    result = run("reference", two_sensors, "-o", tmp_path / "r", "--spp", 1, "--no-progress", "--sensor", 1)
    assert result.exit_code == 0, result.output
    assert read_image(tmp_path / "r.exr").shape[:2] == (8, 16)
    result = run("render", two_sensors, "-o", tmp_path / "c", "--no-progress", "--sensor", 2)
    assert result.exit_code == 2 and "--sensor 2 is not allowed: the scene has 2 sensor(s), 0 to 1" in result.output


def test_edit_on_a_busy_port_is_refused_before_the_first_render(tmp_path):
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        result = run("edit", "--mesh", "bunny", "--material", "marble", "--size-mm", 20, "--width", 16, "--height", 16,
                     "--port", port, "--no-open")
    assert result.exit_code == 2, result.output
    assert f"cannot serve the editor on 127.0.0.1 port {port}" in result.output
    assert "rendering the first preview" not in result.output


@pytest.mark.slow
@pytest.mark.parametrize("requests", [
    [("POST", "/api/update")],  # one edit
    [("GET", "/"), ("GET", "/api/state"), ("GET", "/image.png"), ("GET", "/profile.png")],  # the page, loaded once
])
def test_ctrl_c_ends_the_editor_after_an_edit_or_the_page(requests):
    """Issue 51: after one edit (a render in a request's thread, which lets Mitsuba install its own SIGINT handler),
    and in a fresh editor after the page had loaded once, Ctrl-C only wound renders down and the server kept
    serving; now it ends, exit 130, in one line."""
    import http.client
    import re

    proc = subprocess.Popen([sys.executable, "-m", "convsss", "edit", "--mesh", "bunny", "--material", "marble",
                             "--size-mm", "20", "--width", "32", "--height", "32", "--port", "0", "--no-open"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": _src_path()})
    try:
        line = proc.stdout.readline()
        port = int(re.search(r"http://127\.0\.0\.1:(\d+)/", line).group(1))
        connection = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
        for method, path in requests:
            body = json.dumps({"sigma_a": [0.2, 0.2, 0.2]}) if method == "POST" else None
            connection.request(method, path, body, {"Content-Type": "application/json"} if body else {})
            response = connection.getresponse()
            assert response.status == 200 and response.read()
        time.sleep(1.0)  # serve_forever's loop turns (0.5 s) between requests
        proc.send_signal(signal.SIGINT)
        stderr = proc.communicate(timeout=30)[1]
    finally:
        proc.kill()
    assert proc.returncode == 130 and "Traceback" not in stderr and stderr.rstrip().endswith("interrupted"), stderr


def test_an_output_name_that_is_not_utf8_is_refused_before_any_work(tmp_path):
    name = os.fsdecode(bytes(tmp_path / "x") + b"\xff")  # what Python makes of a non-UTF-8 argument
    result = run("render", "--mesh", "bunny", "--material", "marble", "--size-mm", 20, "-o", name, "--no-progress")
    assert result.exit_code == 2 and "is not a valid UTF-8 name" in result.output, result.output
    assert not any(tmp_path.iterdir())


def test_edit_help_states_the_defaults_it_uses():
    """Issue 30: `edit --help` said 800 pixels and 16 spp with --mesh; the editor previews 256² at 1 spp."""
    text = " ".join(run("edit", "--help").output.split())
    assert text.count("default 256 (the scene's film is resized)") == 2 and "(default 1)" in text
    assert "800 with --mesh" not in text


@pytest.mark.slow
def test_progress_is_plain_lines_when_stderr_is_no_terminal(scene_file, tmp_path):
    """Issue 30 (friction): logs of render and reference, stderr piped, have one line per stage or pass and no
    carriage return."""
    env = {**os.environ, "PYTHONPATH": _src_path()}
    for args in (["render", str(scene_file), "-o", str(tmp_path / "a"), "--spp", "1", "--width", "16", "--height",
                  "16"],
                 ["reference", str(scene_file), "-o", str(tmp_path / "b"), "--spp", "2", "--pass-spp", "1",
                  "--width", "16", "--height", "16"]):
        result = subprocess.run([sys.executable, "-m", "convsss", *args], capture_output=True, text=True,
                                timeout=300, env=env)
        assert result.returncode == 0, result.stderr
        assert "\r" not in result.stderr
    assert "render: shading (7/8) at" in subprocess.run(
        [sys.executable, "-m", "convsss", "render", str(scene_file), "-o", str(tmp_path / "c"), "--spp", "1",
         "--width", "16", "--height", "16", "--walk-depth", "0"], capture_output=True, text=True, timeout=300,
        env=env).stderr


def test_progress_counts_passes_once_the_integrator_names_them(capsys):
    """A render in passes: a line per pass, each stage's line once (the first pass), the bar's total the passes."""
    from convsss.cli.render import StageProgress

    bar = StageProgress(enabled=True, terminal=False)
    for stage in ("scene_load", "pass 1/3", "samples", "shading", "pass 2/3", "samples", "shading", "pass 3/3"):
        bar(stage)
    assert (bar.bar.total, bar.bar.n) == (3, 2)
    bar.close()
    lines = [line.split(" at ")[0] for line in capsys.readouterr().err.splitlines()]
    assert lines == ["render: scene_load (1/8)", "render: pass 1/3", "render: samples", "render: shading",
                     "render: pass 2/3", "render: pass 3/3", "render: done"]


def test_scene_with_an_albedo_volume(mi, tmp_path):
    """--volume: the interior is Mitsuba's heterogeneous medium of the file's albedo over the object's box, named
    relative to the scene; it loads as an object of classes. A file that is not a volume, or not an albedo, is one
    line and exit code 2, and nothing is written."""
    from convsss import material
    from convsss.pipeline.objects import find_translucent_objects
    from convsss.scene.loading import load_scene

    x = (np.arange(16) + 0.5) / 16
    albedo = np.where((x < 0.5)[None, None, :, None], 0.9, 0.999) * np.ones((16, 16, 16, 3))
    (tmp_path / "grids").mkdir()
    mi.VolumeGrid(albedo.astype(np.float32)).write(str(tmp_path / "grids" / "halves.vol"))
    out = tmp_path / "halves.xml"
    result = run("scene", "--material", "marble", "--size-mm", 20, "--boundary", "null", "--width", 8, "--height", 8,
                 "--volume", tmp_path / "grids" / "halves.vol", "-o", out)
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert '<medium type="heterogeneous" name="interior">' in text
    assert '<volume type="gridvolume" name="albedo">' in text
    assert '<string name="filename" value="grids/halves.vol"/>' in text
    (obj,) = find_translucent_objects(mi, load_scene(out))
    assert obj.classes is not None and len(obj.class_profiles) >= 2
    np.testing.assert_allclose(obj.material.sigma_t_prime, material("marble").sigma_t_prime, rtol=1e-5)
    mi.VolumeGrid(np.full((2, 2, 2, 1), 1.5, dtype=np.float32)).write(str(tmp_path / "bright.vol"))
    for bad, words in ((tmp_path / "halves.xml", "not a Mitsuba grid volume"), (tmp_path / "bright.vol", "[0, 1]")):
        result = run("scene", "--material", "marble", "--size-mm", 20, "--volume", bad, "-o", tmp_path / "bad.xml")
        assert result.exit_code == 2 and words in result.output and len(result.output.strip().splitlines()) == 1
        assert not (tmp_path / "bad.xml").exists()


def test_scene_with_a_colour_texture(mi, tmp_path):
    """--color-texture: the interior is a convsss_medium of the bitmap (named relative to the scene) at --mfp-mm; it
    loads as the heterogeneous medium of the texture. A mesh without texture coordinates, a missing --mfp-mm or a
    colour given twice are one line and exit code 2, and nothing is written."""
    from convsss.pipeline.objects import find_translucent_objects
    from convsss.scene.loading import load_scene

    mi.Bitmap(np.full((8, 16, 3), 0.5, dtype=np.float32)).write(str(tmp_path / "paint.exr"))
    cube = tmp_path / "cube.obj"  # closed, wound outwards, uv = (x, y) over the box
    corners = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    cube.write_text("\n".join([f"v {x} {y} {z}" for x, y, z in corners]
                              + [f"vt {(x + 1) / 2} {(y + 1) / 2}" for x, y, _ in corners]
                              + [f"f {a}/{a} {b}/{b} {c}/{c}\nf {a}/{a} {c}/{c} {d}/{d}" for a, b, c, d in faces])
                    + "\n")
    out = tmp_path / "painted.xml"
    result = run("scene", "--mesh", cube, "--color-texture", tmp_path / "paint.exr", "--mfp-mm", 1.5,
                 "--size-mm", 20, "--width", 8, "--height", 8, "-o", out)
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert '<medium type="convsss_medium" name="interior">' in text
    assert '<texture type="bitmap" name="color">' in text and 'value="paint.exr"' in text
    (obj,) = find_translucent_objects(mi, load_scene(out))
    assert obj.shape.interior_medium().class_name() == "HeterogeneousMedium"
    np.testing.assert_allclose(obj.material.mfp_mm, 1.5, rtol=1e-5)
    texture = ["--color-texture", tmp_path / "paint.exr", "--size-mm", 20, "-o", tmp_path / "bad.xml"]
    for args, words in ((["--mesh", "bunny", "--mfp-mm", 1.5], "has no texture coordinates"),
                        (["--mesh", cube, "--mfp-mm", 1.5, "--material", "skin1"], "and --material given"),
                        (["--mesh", cube], "needs --mfp-mm")):
        result = run("scene", *args, *texture)
        assert result.exit_code == 2 and words in result.output and len(result.output.strip().splitlines()) == 1
        assert not (tmp_path / "bad.xml").exists()


@pytest.mark.slow
def test_render_denoise_writes_a_denoised_image_beside_the_raw_one(tmp_path, scene_file):
    """Issue 61 item 3: --denoise adds OUT.denoised.exr/.png (3 channels) and never replaces the raw image; the raw
    EXR holds the guides (albedo, normal AOVs); the stats say so. A scene file's gaussian filter is warned about."""
    import json

    from convsss.image import read_image, read_layers

    out = tmp_path / "b"
    result = run("render", "--mesh", "bunny", "--material", "skin1", "--size-mm", 10, "--width", 32, "--height", 32,
                 "--spp", 2, "--walk-depth", "inf", "--denoise", "-o", out, "--stats", tmp_path / "s.json",
                 "--no-progress")
    assert result.exit_code == 0, result.output
    assert "b.denoised.exr" in result.output and "b.denoised.png" in result.output
    raw, clean = read_image(tmp_path / "b.exr"), read_image(tmp_path / "b.denoised.exr")
    assert clean.shape == (32, 32, 3) and not np.array_equal(raw[..., :3], clean)
    assert {"albedo", "normal"} <= set(read_layers(tmp_path / "b.exr"))
    stats = json.loads((tmp_path / "s.json").read_text())
    assert "Open Image Denoise" in stats["denoised"] and stats["seconds"]["denoise"] > 0
    assert (tmp_path / "b.denoised.png").stat().st_size > 100
    result = run("render", scene_file, "-o", tmp_path / "m", "--walk-depth", "inf", "--spp", 1, "--denoise",
                 "--no-progress")
    assert result.exit_code == 0 and "correlates the pixels' noise" in result.output, result.output


@pytest.mark.slow
def test_the_fields_steps_show_in_the_progress(tmp_path):
    """Issue 62: a finite --walk-depth showed nothing inside its field's stage (10-36 s); each step is said now."""
    result = run("render", "--mesh", "bunny", "--material", "wholemilk", "--size-mm", 20, "--width", 16, "--height", 16,
                 "--spp", 1, "--walk-depth", 4, "-o", tmp_path / "f")
    assert result.exit_code == 0, result.output
    assert "render: transport: the field of 'object' (1/1): its grid at" in result.stderr
    assert "render: transport: the field of 'object' (1/1): solving" in result.stderr
