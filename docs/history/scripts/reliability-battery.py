"""The reliability battery of issue 30, rebuilt from the issue's descriptions: each case runs as a user would run
it (a fresh ``convsss`` process, or a fresh Python for the API cases) and is classified by what came back.

    PYTHONPATH=src python docs/history/scripts/reliability-battery.py [OUT_DIR]

Classes: ``correct`` (exit 0 and the expected output), ``clear error`` (exit 2 and one ``error:`` line, no
traceback), ``traceback`` (a Python traceback on stderr), ``crash`` (killed by a signal: segfault, abort),
``hang`` (past the time limit), ``wrong`` (exit 0 where a refusal or another result was expected). Prints one row
per case and the counts; the table on docs/benchmarks.md ("Reliability battery") is its output.
"""

import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np

SRC = str(Path(__file__).resolve().parents[2] / "src")
LIMIT = 300  # seconds a case may take before it counts as a hang
SMALL = ["--width", "24", "--height", "24", "--spp", "1", "--no-progress"]


def _env():
    return {**os.environ, "PYTHONPATH": SRC}


def _classify(result, expect):
    """(class, detail) of a finished process; ``expect`` is ``ok`` or ``error``."""
    err = result.stderr or ""
    if result.returncode < 0:
        return "crash", signal.Signals(-result.returncode).name
    if "Traceback (most recent call last)" in err:
        return "traceback", err.strip().splitlines()[-1][:100]
    if expect == "error":
        lines = [line for line in err.strip().splitlines() if line.startswith("error:")]
        if result.returncode == 2 and len(lines) == 1:
            return "clear error", lines[0][:100]
        return "wrong", f"exit {result.returncode}: {err.strip()[-100:]}"
    if result.returncode == 0:
        return "correct", ""
    return "wrong", f"exit {result.returncode}: {err.strip()[-100:]}"


def _run(args, expect, cwd, preexec=None):
    try:
        result = subprocess.run(args, capture_output=True, text=True, timeout=LIMIT, env=_env(), cwd=cwd,
                                preexec_fn=preexec)
    except subprocess.TimeoutExpired:
        return "hang", f"> {LIMIT} s"
    return _classify(result, expect)


def cli(*args):
    return [sys.executable, "-m", "convsss", *map(str, args)]


def python(code):
    return [sys.executable, "-c", textwrap.dedent(code)]


def _files(folder):
    """The test files the cases read, written into ``folder``."""
    f = Path(folder)
    subprocess.run(cli("scene", "--material", "marble", "--size-mm", 20, "--boundary", "null", "--width", 24,
                       "--height", 24, "--spp", 1, "-o", f / "base.xml"), check=True, env=_env(),
                   capture_output=True)
    base = (f / "base.xml").read_text()
    shape_end = base.index("</shape>")
    (f / "emitting.xml").write_text(base[:shape_end] + '<emitter type="area"><rgb name="radiance" value="0.5"/>'
                                    "</emitter>" + base[shape_end:])
    lamp = re.search(r'<emitter type="point" id="key_light">.*?</emitter>', base, re.S).group(0)
    inside = re.sub(r'name="position" value="[^"]*"', 'name="position" value="0, 5, 0"', lamp)
    (f / "lamp_inside.xml").write_text(base.replace(lamp, inside))
    (f / "negative.xml").write_text(re.sub(r'(<emitter type="point" id="key_light">.*?name="intensity" value=")'
                                           r'[^"]*', r"\g<1>-1, -1, -1", base, flags=re.S))
    (f / "nan.xml").write_text(re.sub(r'(<emitter type="point" id="key_light">.*?name="intensity" value=")'
                                      r'[^"]*', r"\g<1>nan, nan, nan", base, flags=re.S))
    (f / "deep.xml").write_text('<scene version="3.0.0">' + "<transform name='t'>" * 20_000
                                + "</transform>" * 20_000 + "</scene>")
    (f / "a.xml").write_text('<scene version="3.0.0"><include filename="b.xml"/></scene>')
    (f / "b.xml").write_text('<scene version="3.0.0"><include filename="a.xml"/></scene>')
    shape = base.index("<shape")
    (f / "inf.xml").write_text(base[:shape] + base[shape:].replace(
        '<transform name="to_world">', '<transform name="to_world"><translate x="inf"/>', 1))
    (f / "camera_inf.xml").write_text(base.replace('<transform name="to_world">',
                                                   '<transform name="to_world"><translate x="inf"/>', 1))
    tetra = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype="<f4")
    table = np.zeros(4, dtype=[("n", "u1"), ("i", "<i4", (3,))])
    table["n"], table["i"] = 3, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3_000_000]]
    (f / "badface.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
                                    b"property float y\nproperty float z\nelement face 4\n"
                                    b"property list uchar int vertex_indices\nend_header\n" + tetra.tobytes()
                                    + table.tobytes())
    cube = "".join(f"v {x} {y} {z}\n" for x in (0, 1) for y in (0, 1) for z in (0, 1))
    faces = ["1 2 4 3", "5 7 8 6", "2 6 5 1", "3 4 8 7", "1 3 7 5", "2 6 8 4"]  # the third face flipped
    (f / "mixed.obj").write_text(cube + "".join(f"f {x}\n" for x in faces))
    (f / "huge.csv").write_text("r_mm,R,G,B\n0.1,1,1,1\n1e300,0.001,0.001,0.001\n")
    rough = base.replace('<bsdf type="null">', '<bsdf type="roughdielectric"><float name="alpha" value="-0.3"/>'
                                               '<float name="int_ior" value="1.5"/>')
    (f / "rough.xml").write_text(rough)
    return f


def cases(f):
    """(name, command, expect, preexec): every case, from the issue's list of defects."""
    out = f / "out"
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen()
    port = busy.getsockname()[1]
    one_cpu = min(os.sched_getaffinity(0))
    api = "import convsss\nmi = convsss.register()\nscene = mi.load_file({!r})\n".format(str(f / "base.xml"))
    yield "1 dense medium, 96² (refused before any work)", cli(
        "render", "--mesh", "bunny", "--material", "spectralon", "--size-mm", 40, "--width", 96, "--height", 96,
        "--spp", 4, "-o", out / "spectralon", "--no-progress"), "error", None
    yield "1 dense medium, pbd profile", cli(
        "render", "--mesh", "bunny", "--material", "spectralon", "--size-mm", 40, "--width", 96, "--height", 96,
        "--spp", 4, "--profile", "pbd", "-o", out / "spectralon-pbd", "--no-progress"), "error", None
    yield "2 translucent shape that is an area emitter", cli("render", f / "emitting.xml", "-o", out / "emit",
                                                             *SMALL), "ok", None
    yield "3 PLY face index beyond the vertices", cli("render", "--mesh", f / "badface.ply", "--material", "marble",
                                                      "--size-mm", 10, "-o", out / "ply", *SMALL), "error", None
    yield "3 XML nested 20 000 deep", cli("render", f / "deep.xml", "-o", out / "deep", *SMALL), "error", None
    yield "8 point light inside the object", cli("render", f / "lamp_inside.xml", "-o", out / "inside", *SMALL), \
        "error", None
    yield "8 negative emitter intensity", cli("render", f / "negative.xml", "-o", out / "neg", *SMALL), "error", None
    yield "8 NaN emitter intensity", cli("render", f / "nan.xml", "-o", out / "nan", *SMALL), "error", None
    yield "8 mixed triangle winding", cli("render", "--mesh", f / "mixed.obj", "--material", "marble", "--size-mm",
                                          10, "-o", out / "mixed", *SMALL), "error", None
    yield "8 roughdielectric alpha -0.3", cli("render", f / "rough.xml", "-o", out / "rough", *SMALL), "error", None
    yield "9 object 1e6 mm", cli("render", "--mesh", "bunny", "--material", "wholemilk", "--size-mm", 1e6, "-o",
                                 out / "big", *SMALL), "error", None
    yield "9 sigma_t 1e6/mm (a colour at 1e-6 mm mfp)", cli(
        "render", "--mesh", "bunny", "--color", "0.5,0.5,0.5", "--mfp-mm", 1e-6, "--size-mm", 40, "-o",
        out / "dense", *SMALL), "error", None
    yield "10 non-UTF-8 output name", cli("render", "--mesh", "bunny", "--material", "marble", "--size-mm", 20,
                                          "-o", os.fsdecode(bytes(out) + b"/\xff"), *SMALL), "error", None
    yield "10 include cycle", cli("render", f / "a.xml", "-o", out / "cycle", *SMALL), "error", None
    yield "10 profile CSV with a radius of 1e300", cli("profile", "plot", f / "huge.csv", "-o", out / "huge.png"), \
        "error", None
    yield "10 edit --port BUSY", cli("edit", "--mesh", "bunny", "--material", "marble", "--size-mm", 20, "--port",
                                     port, "--no-open", "--width", 16, "--height", 16), "error", None
    yield "10 API seed=-1", python(api + "convsss.render(scene, seed=-1)"), "error-api", None
    yield "10 API seed=2**40", python(api + "convsss.render(scene, seed=2**40)"), "error-api", None
    yield "10 API render(None)", python(api + "convsss.render(None)"), "error-api", None
    yield "10 API spp=-4", python(api + "convsss.render(scene, spp=-4)"), "error-api", None
    yield "10 API sensor=5", python(api + "convsss.render(scene, sensor=5)"), "error-api", None
    yield "11 one CPU (taskset -c 0)", cli("render", f / "base.xml", "-o", out / "onecpu", *SMALL), "ok", \
        (lambda: os.sched_setaffinity(0, {one_cpu}))
    yield "14 --color 1,1,1 under exact", cli("render", "--mesh", "bunny", "--color", "1,1,1", "--mfp-mm", 1,
                                              "--color-model", "exact", "--size-mm", 20, "-o", out / "white",
                                              *SMALL), "error", None
    yield "14 infinite translate of the object", cli("render", f / "inf.xml", "-o", out / "inf", *SMALL), "error", \
        None
    yield "14 infinite translate of the camera", cli("render", f / "camera_inf.xml", "-o", out / "caminf", *SMALL), \
        "error", None
    yield "the scene as written renders", cli("render", f / "base.xml", "-o", out / "base", *SMALL), "ok", None
    busy.close()


def main(folder=None):
    folder = Path(folder or tempfile.mkdtemp(prefix="convsss-battery-"))
    folder.mkdir(parents=True, exist_ok=True)
    f = _files(folder)
    counts = {}
    for name, command, expect, preexec in cases(f):
        if expect == "error-api":  # a ConvsssError raised to the caller, not a traceback of another type
            try:
                result = subprocess.run(command, capture_output=True, text=True, timeout=LIMIT, env=_env())
                last = (result.stderr.strip().splitlines() or [""])[-1]
                kind = ("clear error", last[:100]) if last.startswith("convsss.errors.ConvsssError") else \
                    ("crash", str(result.returncode)) if result.returncode < 0 else ("traceback", last[:100])
            except subprocess.TimeoutExpired:
                kind = ("hang", f"> {LIMIT} s")
        else:
            kind = _run(command, expect, folder, preexec)
        counts[kind[0]] = counts.get(kind[0], 0) + 1
        print(f"| {name} | {kind[0]} | {kind[1].replace('|', '/')} |", flush=True)
    print()
    print(" · ".join(f"{k}: {v}" for k, v in sorted(counts.items())))


if __name__ == "__main__":
    main(*sys.argv[1:])
