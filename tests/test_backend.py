"""Which Mitsuba variant convsss renders in. Variants are switched in subprocesses: a switch in this process would
change the variant every other test runs in."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import convsss
from convsss.backend import DEFAULT_VARIANT, SUPPORTED_VARIANTS

# Each snippet prints one JSON line: the variant after each step and the message of each error.
PROLOGUE = """
import json, convsss
from convsss.llvm import ensure_llvm
ensure_llvm()                      # a user whose Mitsuba finds LLVM
import mitsuba as mi
out = {}
def attempt(name, call):
    try:
        call()
        out[name] = "ok"
    except convsss.ConvsssError as error:
        out[name] = "ConvsssError: " + str(error)
    out[name + " variant"] = mi.variant()
"""


def _run(code):
    env = {**os.environ, "PYTHONPATH": str(Path(convsss.__file__).parents[1])}
    proc = subprocess.run([sys.executable, "-c", PROLOGUE + code + "\nprint(json.dumps(out))"], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def switching():
    return _run("""
mi.set_variant("scalar_rgb")
attempt("scalar", convsss.register)
mi.set_variant("llvm_ad_spectral")
attempt("spectral", convsss.register)
attempt("requested mono", lambda: convsss.register("llvm_ad_mono"))
attempt("requested rgb", lambda: convsss.register("llvm_ad_rgb"))
attempt("load", lambda: mi.load_dict({"type": "convsss"}))
import convsss.backend
convsss.backend.SUPPORTED_VARIANTS += ("llvm_ad_mono",)   # a second variant the loaded classes were not built in
mi.set_variant("llvm_ad_mono")
attempt("second variant", convsss.register)
""")


def test_supported_variants_are_jit_rgb():
    assert DEFAULT_VARIANT in SUPPORTED_VARIANTS
    assert all(v.endswith("_rgb") and not v.startswith("scalar") for v in SUPPORTED_VARIANTS)


@pytest.mark.slow
def test_no_active_variant_sets_the_default():
    out = _run('attempt("register", convsss.register)')
    assert out == {"register": "ok", "register variant": DEFAULT_VARIANT}


@pytest.mark.slow
def test_active_supported_variant_is_kept():
    out = _run(f'mi.set_variant("{DEFAULT_VARIANT}")\nattempt("register", convsss.register)')
    assert out == {"register": "ok", "register variant": DEFAULT_VARIANT}


@pytest.mark.parametrize("case, variant", [("scalar", "scalar_rgb"), ("spectral", "llvm_ad_spectral"),
                                           ("requested mono", "llvm_ad_mono")])
@pytest.mark.slow
def test_unsupported_variant_is_refused_in_one_line_and_left_alone(switching, case, variant):
    message = switching[case]
    assert message.startswith(f"ConvsssError: Mitsuba variant '{variant}'") and "\n" not in message
    assert all(v in message for v in SUPPORTED_VARIANTS)
    assert switching[case + " variant"] == ("llvm_ad_spectral" if case == "requested mono" else variant)


def test_requested_variant_is_set_and_the_plugin_loads(switching):
    assert switching["requested rgb"] == "ok" and switching["requested rgb variant"] == "llvm_ad_rgb"
    assert switching["load"] == "ok"


def test_second_variant_in_one_process_is_refused(switching):
    assert switching["second variant"].startswith("ConvsssError: convsss was loaded in Mitsuba variant "
                                                  "'llvm_ad_rgb'")


@pytest.mark.slow
def test_exr_files_are_written_and_read_on_one_cpu(tmp_path):
    """Issue 30, defect 11: pinned to one CPU (``taskset -c 0``, CPU-pinned containers), Mitsuba's EXR writer and
    reader hung forever; Dr.Jit's pool keeps two threads."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = ("import numpy as np\nfrom convsss.image import exr_writer, read_image\n"
            f"exr_writer(np.ones((8, 8, 3)))({str(tmp_path / 'a.exr')!r})\n"
            f"print(read_image({str(tmp_path / 'a.exr')!r}).shape)\n")
    one_cpu = min(os.sched_getaffinity(0))
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                            preexec_fn=lambda: os.sched_setaffinity(0, {one_cpu}),
                            env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")})
    assert result.returncode == 0 and result.stdout.strip() == "(8, 8, 3)", result.stderr


@pytest.mark.slow
def test_a_variant_that_cannot_start_is_one_line():
    """Issue 30, defect 10: convsss.register(variant='cuda_ad_rgb') on a machine without a GPU raised an ImportError
    from deep in Dr.Jit."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = ("import convsss\ntry:\n    convsss.register(variant='cuda_ad_rgb')\n    print('started')\n"
            "except convsss.ConvsssError as error:\n    print('refused:', error)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                            env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")})
    if result.stdout.startswith("started"):
        pytest.skip("this machine starts cuda_ad_rgb")
    assert result.returncode == 0 and result.stdout.startswith("refused: Mitsuba variant 'cuda_ad_rgb' cannot "
                                                                "start on this machine"), result.stderr


def test_importing_a_module_sets_no_variant():
    """Every module but the integrator's (its class derives from the variant's SamplingIntegrator) imports Mitsuba
    without choosing a variant: a user's ``mi.set_variant`` after ``import convsss...`` is theirs to make."""
    code = """
import importlib, json, pkgutil, convsss
from convsss.backend import active_variant
names = [m.name for m in pkgutil.walk_packages(convsss.__path__, "convsss.")]
imported = []
for name in names:
    if name.startswith(("convsss.pipeline.integrator", "convsss.__main__")):
        continue
    module = importlib.import_module(name)
    if active_variant() is not None:
        break
    imported.append(name)
print(json.dumps({"variant": active_variant(), "imported": len(imported), "last": imported[-1:]}))
"""
    env = {**os.environ, "PYTHONPATH": str(Path(convsss.__file__).parents[1])}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["variant"] is None, out
    assert out["imported"] > 80
