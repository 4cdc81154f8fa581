"""The batch runner: every job of a :class:`~.spec.Batch` on Dask distributed, with a manifest kept current.

Each job is one :func:`~convsss.outputs.render_to_files` (or ``reference_to_files``), what ``convsss render`` (or
``reference``) runs, in a Dask worker process, with its own folder
``OUT/jobs/ID/`` (``image.exr``, ``image.png``, with ``render`` ``stats.json``) and, written last, ``job.json``: what
says the job is complete (a second run skips it). A worker that dies (killed, out of memory) has its job run again
elsewhere, up to ``retries`` times (Dask's ``allowed-failures``); a job that fails (bad input found by the command)
is marked failed with its message. ``OUT/manifest.json`` and ``manifest.csv`` are rewritten whole after every job.

By default the jobs run on a :class:`distributed.LocalCluster` of worker processes (one thread each, the machine's
memory shared out); ``scheduler`` submits to a running cluster instead (``tcp://HOST:PORT``), whose workers must have
convsss and the scenes' files at the same paths.
"""

import contextlib
import csv
import io
import json
import logging
import os
import time
import warnings
from pathlib import Path

from ..errors import ConvsssError
from ..files import atomic_write
from .spec import keywords

#: A job's complete marker, written last in its folder.
DONE = "job.json"
#: Seconds a scheduler has to answer before the batch gives up on it.
CONNECT_SECONDS = 20


def job_folder(out, job):
    return Path(out) / "jobs" / job.id


def run_job(command, job_id, keywords, folder):
    """Run one job in this process: :func:`~convsss.outputs.render_to_files` (``command`` ``render``, with its stats)
    or :func:`~convsss.outputs.reference_to_files` of ``keywords`` (:func:`~.spec.keywords`) to ``FOLDER/image``;
    returns its record (``seconds``: the render's stages and ``total``; ``outputs``; ``warnings``, each once, one
    line), also written to
    ``FOLDER/job.json``. Bad input raises the function's :class:`ConvsssError`."""
    from ..memory import set_budget
    from ..outputs import reference_to_files, render_to_files

    set_budget(_worker_memory())  # a job that would not fit its worker's share is refused, not killed
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as heard:  # the manifest says them, not the worker's stderr
        warnings.simplefilter("always")
        if command == "render":
            stats = render_to_files(**keywords, output=folder / "image", stats_path=folder / "stats.json")
            seconds = dict(stats["seconds"])
        else:
            stats = reference_to_files(**keywords, output=folder / "image")
            seconds = {}
    seconds["total"] = time.perf_counter() - start
    outputs = {k: v for k, v in stats["outputs"].items() if k in ("exr", "png", "stats")}
    record = {"id": job_id, "status": "done", "seconds": seconds, "worker_pid": os.getpid(), "outputs": outputs,
              "warnings": list(dict.fromkeys(" ".join(str(w.message).split()) for w in heard))}
    atomic_write(folder / DONE, lambda tmp: Path(tmp).write_text(json.dumps(record, indent=1)))
    return record


def _worker_memory():
    """The Dask worker's memory limit in bytes, when this runs in one that has a limit; else None."""
    try:
        from distributed import get_worker

        limit = get_worker().memory_manager.memory_limit
    except (ImportError, ValueError, AttributeError):
        return None
    return int(limit) if limit else None


def completed(out, job):
    """The record of ``job`` when its folder holds a complete run (``job.json`` and every output it names)."""
    marker = job_folder(out, job) / DONE
    if not marker.is_file():
        return None
    record = json.loads(marker.read_text())
    return record if all(Path(p).is_file() for p in record.get("outputs", {}).values()) else None


def write_manifest(out, batch, records):
    """``OUT/manifest.json`` (``{"command", "jobs": [...]}``, a job's parameters beside its record) and
    ``OUT/manifest.csv`` (one row a job: id, status, every option, total seconds, error), each written whole."""
    rows = []
    for job in batch.jobs:
        record = records.get(job.id, {"status": "pending"})
        rows.append({"id": job.id, "parameters": job.options, "varied": job.varied,
                     **{k: v for k, v in record.items() if k != "id"}})
    out = Path(out)
    atomic_write(out / "manifest.json", lambda tmp: Path(tmp).write_text(
        json.dumps({"command": batch.command, "jobs": rows}, indent=1, default=str)))
    names = sorted({k for job in batch.jobs for k in job.options})
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow(["id", "status", *names, "seconds", "error"])
    for row in rows:
        writer.writerow([row["id"], row["status"], *(row["parameters"].get(k, "") for k in names),
                         f"{row.get('seconds', {}).get('total', '')}", row.get("error", "")])
    atomic_write(out / "manifest.csv", lambda tmp: Path(tmp).write_text(text.getvalue()))


def check_scheduler(address):
    """A one-line :class:`ConvsssError` unless ``address`` reads as a Dask scheduler's (``tcp://HOST:PORT``, or
    another of Dask's schemes with a host and port): before any work, not a traceback from the connection."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    try:
        scheme, location = parse_address(address)
        get_backend(scheme)
        if scheme != "inproc":
            host, port = parse_host_port(location)
            if not host or port is None:
                raise ValueError("no port")
    except (ValueError, TypeError) as error:
        raise ConvsssError(f"--scheduler {address!r} is not a Dask scheduler's address ({error}): give "
                           "tcp://HOST:PORT") from None


def _connect(scheduler):
    """A Dask client of the scheduler at ``scheduler``, or a one-line :class:`ConvsssError` within
    :data:`CONNECT_SECONDS` (Dask's own timeout does not end a handshake that a listener of another kind never
    answers)."""
    import threading

    from distributed import Client

    check_scheduler(scheduler)
    result = {}

    def connect():
        try:
            result["client"] = Client(scheduler, timeout="10s")
        except Exception as error:  # handed back to the caller, one line
            result["error"] = error

    thread = threading.Thread(target=connect, name="convsss-dask-connect", daemon=True)
    thread.start()
    thread.join(CONNECT_SECONDS)
    if thread.is_alive():
        raise ConvsssError(f"no Dask scheduler answers at {scheduler} within {CONNECT_SECONDS} s (something listens "
                           "there, but not a Dask scheduler?)")
    if "error" in result:
        error = result["error"]
        raise ConvsssError(f"no Dask scheduler answers at {scheduler}: {' '.join(str(error).split())}")
    return result["client"]


def make_folder(out):
    """The batch's folder made (with its parents), or a one-line :class:`ConvsssError` saying why it cannot be."""
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ConvsssError(f"cannot make the folder {str(out)!r}: {error.strerror or error}") from None
    return out


@contextlib.contextmanager
def _cluster(scheduler, workers, retries):
    """A Dask client, closed on leaving: to ``scheduler``, or to a new local cluster of ``workers`` processes (one
    thread each), closed with it."""
    import dask
    from distributed import Client, LocalCluster

    dask.config.set({"distributed.scheduler.allowed-failures": retries,
                     "distributed.worker.daemon": False, "distributed.admin.tick.limit": "1h"})
    if scheduler:
        client = _connect(scheduler)
        with client:
            yield client
        return
    workers = workers or os.cpu_count() or 1
    # Its workers log at CRITICAL only: a failing job is the manifest's one line (and the command's), not Dask's
    # "Compute Failed" and the worker's traceback on our stderr beside it.
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.CRITICAL)
    with cluster, Client(cluster) as client:
        yield client


def on_cluster(function, calls, scheduler=None, workers=None, retries=3, progress=True, desc="tasks", echo=print):
    """``function(*args)`` for every ``args`` of ``calls`` on Dask workers (a local cluster of ``workers``
    processes, or ``scheduler``'s); returns each call's result or the exception it raised, in order (a call whose
    worker died on every try: a :class:`ConvsssError` saying so)."""
    with _cluster(scheduler, workers, retries) as client:
        return _gather(client, function, calls, retries, progress, desc, echo)


def _gather(client, function, calls, retries, progress, desc, echo):
    """:func:`on_cluster` on ``client``."""
    from distributed import as_completed
    from tqdm import tqdm

    futures = {client.submit(function, *args, key=f"convsss-{desc}-{k}-{time.time_ns()}", pure=False): k
               for k, args in enumerate(calls)}
    results = [None] * len(futures)
    bar = tqdm(total=len(futures), desc=desc, unit="task", disable=not progress)
    try:
        if client.dashboard_link:
            echo(f"{desc}: {len(futures)} on Dask; dashboard {client.dashboard_link}")
        for future in as_completed(futures):
            try:
                results[futures[future]] = future.result()
            except Exception as error:  # handed back: the caller says what failed
                results[futures[future]] = ConvsssError(_failure(error, retries))
            bar.update()
    except KeyboardInterrupt:
        for future in futures:
            future.cancel()
        raise
    finally:
        bar.close()
    return results


def run_batch(batch, out, scheduler=None, workers=None, retries=3, job_function=run_job, echo=print,
              progress=True):
    """Run ``batch``'s jobs that ``out`` does not hold complete yet; returns ``{job id: record}``.

    ``job_function(command, job_id, keywords, folder)`` runs one job in a worker (:func:`run_job`; a test may give its
    own). Ctrl-C cancels what is left and writes the manifest of what finished before it re-raises."""
    out = make_folder(Path(out).resolve())  # the workers' own working folder is not ours
    records = {}
    for job in batch.jobs:
        done = completed(out, job)
        if done is not None:
            records[job.id] = {**done, "status": "done", "skipped": True}
    todo = [job for job in batch.jobs if job.id not in records]
    write_manifest(out, batch, records)
    if not todo:
        echo(f"batch: all {len(batch.jobs)} jobs complete in {out}; nothing to run")
        return records
    try:
        with _cluster(scheduler, workers, retries) as client:
            _run_jobs(client, batch, todo, out, records, retries, job_function, echo, progress)
    finally:
        for job in todo:  # a job a worker finished while the batch stopped is complete on disk
            done = completed(out, job) if records.get(job.id, {}).get("status") != "done" else None
            if done is not None:
                records[job.id] = done
        write_manifest(out, batch, records)
    return records


def _run_jobs(client, batch, todo, out, records, retries, job_function, echo, progress):
    """:func:`run_batch`'s jobs ``todo`` on ``client``, ``records`` and the manifest updated as each ends."""
    from distributed import as_completed
    from tqdm import tqdm

    bar = tqdm(total=len(todo), desc="batch", unit="job", disable=not progress)
    futures = {}
    try:
        if client.dashboard_link:
            echo(f"batch: {len(todo)} jobs ({len(batch.jobs) - len(todo)} complete already); Dask dashboard "
                 f"{client.dashboard_link}")
        for job in todo:
            future = client.submit(job_function, batch.command, job.id, keywords(batch.parser, job.options),
                                   str(job_folder(out, job)), key=f"convsss-{job.id}-{time.time_ns()}", pure=False)
            futures[future] = job
            records[job.id] = {"status": "queued"}
        for future in as_completed(futures):
            job = futures[future]
            records[job.id] = _outcome(future, retries)
            bar.update()
            write_manifest(out, batch, records)
    except KeyboardInterrupt:
        for future, job in futures.items():
            if not future.done():
                future.cancel()
                records[job.id] = {"status": "cancelled"}
        raise
    finally:
        bar.close()


def _failure(error, retries):
    """What a job's or a task's exception says, in one line."""
    from distributed import KilledWorker

    if isinstance(error, KilledWorker):
        return f"its worker died on every try ({retries} allowed; killed or out of memory)"
    if isinstance(error, ConvsssError):
        return str(error)
    return f"{type(error).__name__}: {error}"


def _outcome(future, retries):
    """A finished job's record: its result, or ``failed`` with the reason (the batch goes on)."""
    try:
        return future.result()
    except Exception as error:  # the command's own failure, reported in its manifest row
        return {"status": "failed", "error": _failure(error, retries)}
