"""numba loaded on the first call of a compiled function, not at import (each check in a fresh interpreter)."""

import subprocess
import sys
from pathlib import Path

import pytest

import convsss

SRC = str(Path(convsss.__file__).parents[1])


def python(code):
    """The last line ``code`` prints, run by a fresh interpreter that imports this ``convsss``."""
    result = subprocess.run([sys.executable, "-c", f"import sys\nsys.path.insert(0, {SRC!r})\n{code}"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    return result.stdout.strip().splitlines()[-1]


def test_first_call_loads_numba_and_puts_its_functions_in_place():
    """Importing every transport loads no numba; the first call does, and from then on each module holds numba's
    functions: a compiled function calling another (``grown`` calls ``empty``), and one parallel over ``prange``
    that calls inlined ones (the slab's photon walk) give what they give with numba loaded first (no deferral)."""
    code = """
import convsss.transport, convsss.pipeline.irradiance, convsss.profiles.slab as slab
from convsss import hashtable
before = "numba" in sys.modules
keys, values = hashtable.grown(*hashtable.empty(16), 64)
tally = slab.slab_tally(0.9, 1.3, photons=1 << 12, seed=3)
import numba
print(before, len(keys), int(values.max()), isinstance(hashtable.empty, numba.core.dispatcher.Dispatcher),
      isinstance(slab._walk, numba.core.dispatcher.Dispatcher), repr(tally["total"]))
"""
    deferred, loaded_first = python(code).split(), python("import numba\n" + code).split()
    assert deferred[:5] == ["False", "64", "-1", "True", "True"] and loaded_first[0] == "True"
    assert deferred[1:] == loaded_first[1:]


@pytest.mark.slow
def test_a_walked_render_never_loads_numba(tmp_path):
    """A render that walks runs no numba loop, so it does not pay numba's import (0.15 s of every command)."""
    code = f"""
from convsss.cli import main
try:
    main(["render", "--mesh", "bunny", "--material", "wholemilk", "--size-mm", "4", "--width", "16", "--height",
          "16", "--spp", "1", "--walk-depth", "inf", "-o", {str(tmp_path / "walked")!r}, "--no-progress"])
except SystemExit as exit:
    assert not exit.code, exit.code
print("numba" in sys.modules)
"""
    assert python(code) == "False"
