import json
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import quad

from convsss import __version__
from convsss.cli import cli


def run(*args):
    return CliRunner().invoke(cli, list(args))


def test_help_and_version():
    assert "materials" in run("--help").output
    assert __version__ in run("--version").output


def test_version_imports_no_command_nor_numpy():
    """Issue 33 (nothing twice): `convsss --version` loads no command module and neither numpy nor scipy (1.3 s of
    imports before, 0.06 s after); a command's module is imported when the command runs."""
    code = ("import sys\nfrom convsss.cli import main\ntry:\n    main(['--version'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'scipy', 'numba') or "
            "m.startswith('convsss.cli.') and m != 'convsss.cli.main'))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "[]"
    assert "List the measured material presets" in run("materials", "--help").output


def _independent_total(s, a, eta):
    """Total diffuse reflectance by integrating a separately written dipole numerically."""
    st = s + a
    alpha = s / st
    sigma_tr = np.sqrt(3 * a * st)
    fdr = -1.4399 / eta**2 + 0.7099 / eta + 0.6681 + 0.0636 * eta
    zr = 1 / st
    zv = zr * (1 + 4 / 3 * (1 + fdr) / (1 - fdr))

    def rd(r):
        out = 0.0
        for z in (zr, zv):
            d = np.hypot(r, z)
            out += z * (sigma_tr + 1 / d) * np.exp(-sigma_tr * d) / d**2
        return alpha / (4 * np.pi) * out

    return quad(lambda u: 2 * np.pi * np.exp(2 * u) * rd(np.exp(u)), np.log(1e-7), np.log(1e7), limit=1000)[0]


def test_materials_json_matches_independent_implementation():
    result = run("materials", "--json")
    assert result.exit_code == 0, result.output
    rows = json.loads(result.output)
    assert len(rows) == 47
    for row in rows:
        assert set(row) == {"name", "sigma_s_prime", "sigma_a", "eta", "total_reflectance", "mfp_mm",
                            "diffusion_length_mm"}
        assert isinstance(row["eta"], float)
        for c in range(3):
            expected = _independent_total(row["sigma_s_prime"][c], row["sigma_a"][c], row["eta"])
            assert row["total_reflectance"][c] == pytest.approx(expected, abs=1e-3), (row["name"], c)
    spectralon = next(r for r in rows if r["name"] == "Spectralon")
    assert spectralon["diffusion_length_mm"] == [None, None, None]


def test_materials_table():
    result = run("materials")
    assert result.exit_code == 0
    lines = result.output.splitlines()
    assert len(lines) == 48 and lines[0].startswith("name")
    assert any(line.startswith("Wholemilk") and "0.908/0.881/0.759" in line for line in lines)


@pytest.mark.slow
def test_console_script_reports_bad_input_in_one_line():
    # The installed entry point, as a user runs it: a bad input is one line on stderr and exit code 2.
    code = "from convsss.cli import cli\n" \
           "from convsss.materials import material\n" \
           "import click\n" \
           "@cli.command()\n" \
           "def probe():\n    material('wholemilkk')\n" \
           "cli.main(args=['probe'], prog_name='convsss')\n"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0
    assert proc.stderr.startswith("error: unknown material 'wholemilkk'; did you mean 'Wholemilk'")
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("raised, code, said", [
    ("KeyboardInterrupt", 130, "interrupted\n"),
    ("MemoryError", 2, "error: out of memory"),  # one the guard could not foresee (another process took the memory)
])
def test_ctrl_c_and_memory_end_any_command_in_one_line(raised, code, said):
    code_text = "from convsss.cli import cli\n" \
                "@cli.command()\n" \
                f"def probe():\n    raise {raised}\n" \
                "cli.main(args=['probe'], prog_name='convsss')\n"
    proc = subprocess.run([sys.executable, "-c", code_text], capture_output=True, text=True)
    assert proc.returncode == code and proc.stderr.startswith(said) and proc.stderr.count("\n") == 1


# ---- compare and figures: outputs never overwrite inputs, one-line errors, nothing written ---------------------------
def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() if p.is_file() else None for p in folder.rglob("*")}


@pytest.fixture
def images(tmp_path, monkeypatch):
    """The working directory, with a.exr, b.png and mask.png."""
    from convsss.image import write_exr, write_png

    rgb = np.random.default_rng(1).random((8, 8, 3))
    write_exr(tmp_path / "a.exr", rgb)
    write_png(tmp_path / "b.png", rgb, method="none")
    write_png(tmp_path / "mask.png", np.ones((8, 8, 3)), method="none")
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("args, message", [
    (("compare", "a.exr", "b.png", "-o", "b.png"), "output 'b.png' is an input of this command"),
    (("compare", "a.exr", "b.png", "-o", "./a.exr"), "output 'a.exr' is an input of this command"),
    (("compare", "a.exr", "b.png", "--mask", "mask.png", "-o", "mask.png"), "is an input of this command"),
    (("compare", "a.exr", "b.png", "-o", "/proc/x/error.png"), "cannot write into '/proc/x'"),
    (("compare", "a.exr", "b.png", "-o", "a.exr/error.png"), "not a folder"),
    (("figures", "--only", ",", "--output", "figs"), "--only ',' names no figure"),
    (("figures", "--output", "/proc/x"), "cannot write into '/proc/x'"),
    (("figures", "--output", "a.exr"), "Invalid value for '-o' / '--output'"),
])
def test_bad_outputs_fail_in_one_line_and_write_nothing(images, args, message):
    before = _snapshot(images)
    result = run(*args)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.stderr
    assert "Traceback" not in result.output and _snapshot(images) == before


@pytest.mark.slow
def test_profile_validate_and_plot_write_their_files(tmp_path):
    runner = CliRunner()
    out = tmp_path / "v"
    result = runner.invoke(cli, ["profile", "validate", "marble", "--photons", "4000", "--model", "dipole",
                                 "--model", "pbd", "-o", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    assert (out / "validate.md").is_file() and (out / "validate.json").is_file() and (out / "marble.png").is_file()
    assert "| Marble | R |" in result.output and "pbd" in result.output and "exact total" in result.output
    cached = sorted(p.name for p in (out / "cache").iterdir())
    assert len(cached) == 3  # one tally per channel, reused by the next run
    assert runner.invoke(cli, ["profile", "validate", "marble", "--photons", "4000", "-o", str(out),
                               "--no-progress"]).exit_code == 0
    assert sorted(p.name for p in (out / "cache").iterdir()) == cached
    csv = tmp_path / "p.csv"
    csv.write_text("r_mm,R,G,B\n0,1,1,1\n1,0.5,0.4,0.3\n2,0,0,0\n")
    result = runner.invoke(cli, ["profile", "plot", "skin1", str(csv), "-o", str(tmp_path / "p.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "p.png").stat().st_size > 0


def test_profile_commands_refuse_bad_input_in_one_line(tmp_path):
    runner = CliRunner()
    result = runner.invoke(cli, ["profile", "validate", "-o", str(tmp_path / "v")])
    assert result.exit_code == 2 and "nothing to validate" in result.output
    result = runner.invoke(cli, ["profile", "plot", "milkk", "-o", str(tmp_path / "p.png")])
    assert result.exit_code == 2 and "unknown material 'milkk'" in result.output


def test_profile_invert_round_trips_the_colour():
    result = CliRunner().invoke(cli, ["profile", "invert", "--color", "0.8,0.5,0.3", "--mfp-mm", "2", "--color-model",
                                      "better-dipole", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    np.testing.assert_allclose(report["color"], [0.8, 0.5, 0.3], rtol=1e-8)
    np.testing.assert_allclose(np.add(report["sigma_s_prime"], report["sigma_a"]), 0.5, rtol=1e-12)
    bad = CliRunner().invoke(cli, ["profile", "invert", "--color", "0.8,0.5", "--mfp-mm", "2"])
    assert bad.exit_code == 2 and "give one number or three" in bad.output


def test_the_clis_model_names_are_the_packages():
    """The CLI names the models without importing the profiles at start-up: its lists must be the package's."""
    from convsss.cli.options import COLOR_MODEL_NAMES, MODEL_NAMES
    from convsss.profiles.models import COLOR_MODELS, PROFILE_MODELS

    assert MODEL_NAMES == tuple(PROFILE_MODELS) and COLOR_MODEL_NAMES == COLOR_MODELS
