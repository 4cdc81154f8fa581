"""Determinism (docs/architecture.md): the same inputs and seed give the same image, byte for byte, whatever the
thread count."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import convsss
from convsss.image import read_layers

#: The command line, with Dr.Jit's thread count from the first argument (Dr.Jit reads no environment variable).
COMMAND = ("import sys, drjit\n"
           "drjit.set_thread_count(int(sys.argv[1]))\n"
           "from convsss.cli import cli\n"
           "cli.main(args=sys.argv[2:], prog_name='convsss')\n")


def render(out, drjit_threads, numba_threads, numba_cache):
    """``convsss render`` of a bunny without vertex normals on a floor (Gaussian film filter) in a new process: its
    RGB and every AOV, stacked."""
    source = str(Path(convsss.__file__).parents[1])
    env = {**os.environ, "NUMBA_NUM_THREADS": str(numba_threads), "NUMBA_CACHE_DIR": str(numba_cache),
           "PYTHONPATH": os.pathsep.join(filter(None, [source, os.environ.get("PYTHONPATH")]))}
    args = ["render", "--mesh", "bunny", "--material", "wholemilk", "--size-mm", "40", "--floor", "--width", "64",
            "--height", "64", "--spp", "16", "--seed", "3", "-o", str(out), "--no-progress", "--aovs",
            "exitance,irradiance,object,mask,depth,normal"]
    proc = subprocess.run([sys.executable, "-c", COMMAND, str(drjit_threads), *args], env=env, capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr
    layers = read_layers(out.with_suffix(".exr"))
    assert len(layers) == 7
    return np.concatenate([layers[name] for name in sorted(layers)], axis=2)


@pytest.mark.slow
def test_same_seed_same_image_whatever_the_threads_and_caches(tmp_path):
    """Mitsuba's vertex normals and its film's filter sum floats from every Dr.Jit thread at once: without a fixed
    order they change in the last bits from run to run. The first run compiles the numba kernels into an empty
    cache, the others load them from it."""
    cache = tmp_path / "numba"
    first = render(tmp_path / "first", drjit_threads=2, numba_threads=1, numba_cache=cache)
    for drjit_threads, numba_threads in ((8, 2), (16, 3)):
        other = render(tmp_path / f"{drjit_threads}", drjit_threads, numba_threads, cache)
        differing = np.count_nonzero((first != other).any(axis=2))
        pixels = first.shape[0] * first.shape[1]
        assert first.tobytes() == other.tobytes(), \
            f"Dr.Jit {drjit_threads} / numba {numba_threads} threads: {differing} of {pixels} pixels differ"
