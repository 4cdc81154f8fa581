"""The batch runner (convsss.batch.runner) on a two-worker Dask LocalCluster: the same images as single renders,
resuming, a killed worker's job retried, a failing job marked failed, and the command line."""

import json
import os
import sys
from pathlib import Path

import cloudpickle
import numpy as np
import pytest
from click.testing import CliRunner

from convsss.batch import batch_from_spec, contact_sheet, run_batch, run_job, turntables
from convsss.batch.spec import keywords
from convsss.cli import cli
from convsss.cli.batch import command_parsers
from convsss.image import read_image

PARSERS = command_parsers()

cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers run this module's job functions

SPEC = {"scene": {"mesh": "bunny", "size_mm": 20, "width": 24, "height": 24, "spp": 1},
        "axes": {"material": ["wholemilk", "marble"], "seed": [1, 2]}}


def _quiet(text):
    pass


@pytest.mark.slow
def test_a_sweep_renders_the_single_renders_and_a_second_run_skips_them(tmp_path):
    batch = batch_from_spec(SPEC, PARSERS)
    records = run_batch(batch, tmp_path / "out", workers=2, echo=_quiet, progress=False)
    assert [records[j.id]["status"] for j in batch.jobs] == ["done"] * 4
    assert len({records[j.id]["worker_pid"] for j in batch.jobs}) == 2  # both workers rendered
    for job in batch.jobs:  # the same command in this process: the same image, bit for bit
        single = run_job(batch.command, job.id, keywords(batch.parser, job.options), tmp_path / "single" / job.id)
        assert np.array_equal(read_image(single["outputs"]["exr"]), read_image(records[job.id]["outputs"]["exr"]))
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert [row["status"] for row in manifest["jobs"]] == ["done"] * 4
    assert manifest["jobs"][0]["parameters"]["material"] == "wholemilk" and "shading" in manifest["jobs"][0]["seconds"]
    assert (tmp_path / "out" / "manifest.csv").read_text().count("\n") == 5
    again = run_batch(batch, tmp_path / "out", workers=2, echo=_quiet, progress=False)
    assert all(again[j.id].get("skipped") for j in batch.jobs)
    assert contact_sheet(batch, again, tmp_path / "out" / "sheet.png").stat().st_size > 0


def _dies_once_then_runs(command, job_id, keywords, folder):
    """A job whose first worker dies mid-job (as one killed or out of memory would)."""
    marker = Path(folder).parent / f"{job_id}.died"
    if job_id.startswith("0000") and not marker.exists():
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.write_text(str(os.getpid()))
        os._exit(1)
    if job_id.startswith("0001"):
        raise ValueError("this job's scene is bad")
    return run_job(command, job_id, keywords, folder)


@pytest.mark.slow
def test_a_killed_worker_is_retried_and_a_failing_job_is_marked_failed(tmp_path, capfd):
    batch = batch_from_spec({"scene": {**SPEC["scene"], "material": "marble"}, "axes": {"orbit_deg": [0, 120, 240]}},
                            PARSERS)
    records = run_batch(batch, tmp_path, workers=2, job_function=_dies_once_then_runs, echo=_quiet, progress=False)
    assert "Compute Failed" not in capfd.readouterr().err  # the failure is the manifest's line, not Dask's log
    first, second, third = (records[j.id] for j in batch.jobs)
    assert first["status"] == "done" and third["status"] == "done"
    assert (tmp_path / "jobs" / f"{batch.jobs[0].id}.died").read_text() != str(first["worker_pid"])
    assert second["status"] == "failed" and "this job's scene is bad" in second["error"]
    movie = turntables(batch, records, tmp_path)
    assert [p.name for p in movie] == ["turntable.png"]
    from PIL import Image

    assert Image.open(movie[0]).n_frames == 2  # the failed frame left out


@pytest.mark.slow
def test_the_command_refuses_a_bad_spec_before_anything_runs_and_runs_a_good_one(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[scene]\nmesh = "bunny"\nsize_mm = 20\nbogus = 1\n[axes]\nmaterial = []\n')
    result = CliRunner().invoke(cli, ["batch", str(bad), "-o", str(tmp_path / "never")])
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 2 and all(line.startswith("error: ") for line in lines)
    assert not (tmp_path / "never").exists()
    good = tmp_path / "good.toml"
    good.write_text('[scene]\nmesh = "bunny"\nmaterial = "skin1"\nsize_mm = 20\nwidth = 16\nheight = 16\nspp = 1\n'
                    '[axes]\nseed = [1, 2]\n')
    result = CliRunner().invoke(cli, ["batch", str(good), "-o", str(tmp_path / "out"), "--workers", "2",
                                      "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "2 of 2 jobs done" in result.stdout and (tmp_path / "out" / "contact_sheet.png").is_file()


@pytest.mark.slow
def test_the_example_sweep_runs(tmp_path):
    """examples/sweep.toml: four jobs at 64², two materials from two sides, and their turntables."""
    spec = Path(__file__).resolve().parents[2] / "examples" / "sweep.toml"
    result = CliRunner().invoke(cli, ["batch", str(spec), "-o", str(tmp_path), "--workers", "2", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "4 of 4 jobs done" in result.stdout
    assert sorted(p.name for p in tmp_path.glob("turntable*.png")) == ["turntable-material=skin1.png",
                                                                       "turntable-material=wholemilk.png"]
    images = [read_image(p) for p in sorted(tmp_path.glob("jobs/*/image.exr"))]
    assert len(images) == 4 and all(img.shape == (64, 64, 3) and img.mean() > 0 for img in images)


@pytest.mark.slow
def test_ctrl_c_stops_the_workers_and_leaves_the_manifest_of_what_finished(tmp_path):
    import signal
    import subprocess
    import time

    spec = tmp_path / "many.toml"
    spec.write_text('[scene]\nmesh = "bunny"\nmaterial = "skin1"\nsize_mm = 20\nwidth = 48\nheight = 48\nspp = 2\n'
                    '[axes]\nseed = [1, 2, 3, 4, 5, 6, 7, 8]\n')
    out = tmp_path / "out"
    child = subprocess.Popen([sys.executable, "-c", "from convsss.cli import main; main()", "batch", str(spec), "-o",
                              str(out), "--workers", "1", "--no-progress"], start_new_session=True,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    manifest = out / "manifest.json"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # until a job is done
        if manifest.is_file() and '"status": "done"' in manifest.read_text():
            break
        time.sleep(0.2)
    os.killpg(child.pid, signal.SIGINT)  # a terminal's Ctrl-C reaches the whole process group
    start = time.monotonic()
    _, stderr = child.communicate(timeout=60)
    assert child.returncode == 130 and "interrupted" in stderr
    assert time.monotonic() - start < 20
    statuses = [job["status"] for job in json.loads(manifest.read_text())["jobs"]]
    # what finished, read back from the jobs' folders once the workers stopped (a job may end as the batch stops)
    assert "done" in statuses and set(statuses) <= {"done", "cancelled"} and statuses.count("done") < 8
    again = subprocess.run([sys.executable, "-c", "from convsss.cli import main; main()", "batch", str(spec), "-o",
                            str(out), "--workers", "1", "--no-progress"], capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and "8 of 8 jobs done" in again.stdout  # resumed
    done = json.loads(manifest.read_text())["jobs"]
    assert sum(bool(job.get("skipped")) for job in done) == statuses.count("done")


@pytest.mark.slow
def test_jobs_go_to_a_running_scheduler(tmp_path):
    """--scheduler: a cluster started elsewhere (here a LocalCluster of this test) runs the jobs; it stays up."""
    from distributed import LocalCluster

    batch = batch_from_spec({"scene": {**SPEC["scene"], "material": "skin1", "width": 16, "height": 16},
                             "axes": {"seed": [1, 2]}}, PARSERS)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        records = run_batch(batch, tmp_path, scheduler=cluster.scheduler_address, echo=_quiet, progress=False)
        assert [records[j.id]["status"] for j in batch.jobs] == ["done", "done"]
        assert cluster.status.name == "running"
    with pytest.raises(Exception, match="no Dask scheduler answers at tcp://127.0.0.1:9"):
        run_batch(batch, tmp_path / "none", scheduler="tcp://127.0.0.1:9", echo=_quiet, progress=False)


def test_a_bad_scheduler_address_or_folder_is_one_line_before_any_work(tmp_path):
    from convsss.batch.runner import check_scheduler, make_folder
    from convsss.errors import ConvsssError

    for address in ("http://[bad", "tcp://[bad", "tcp://host"):
        with pytest.raises(ConvsssError, match="is not a Dask scheduler's address"):
            check_scheduler(address)
    check_scheduler("tcp://127.0.0.1:8786")
    with pytest.raises(ConvsssError, match="cannot make the folder '/proc/x'"):
        make_folder("/proc/x")
    assert make_folder(tmp_path / "a" / "b").is_dir()


def test_a_listener_that_is_no_scheduler_is_given_up_on(monkeypatch):
    """Something listens but never answers Dask's handshake (issue 51: 150 s without a word): a one-line error."""
    import socket

    from convsss.batch import runner
    from convsss.errors import ConvsssError

    monkeypatch.setattr(runner, "CONNECT_SECONDS", 2)
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(1)
        port = listener.getsockname()[1]
        with pytest.raises(ConvsssError, match="within 2 s"):
            runner._connect(f"tcp://127.0.0.1:{port}")


def test_a_jobs_warnings_go_to_its_record_not_the_workers_stderr(tmp_path):
    """Issue 51: a worker printed Python's warning format (file, line, source) beside the manifest's one line."""
    import warnings

    from convsss.batch.spec import keywords

    batch = batch_from_spec({"scene": {**SPEC["scene"], "material": "ketchup", "width": 8, "height": 8}}, PARSERS)
    job = batch.jobs[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # none escapes the job
        record = run_job(batch.command, job.id, keywords(batch.parser, job.options), tmp_path / job.id)
    assert any("not optically thick" in w for w in record["warnings"])
    assert all("\n" not in w for w in record["warnings"])
