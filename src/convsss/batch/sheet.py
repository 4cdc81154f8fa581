"""What a batch shows at a glance: a contact sheet of its images, and turntables as animated PNGs.

Both read the jobs' PNGs (:mod:`.runner`); a job that did not finish is a grey tile on the sheet and is left out of
its turntable.
"""

from pathlib import Path

import numpy as np

from ..files import atomic_write

#: A turntable's frames per second.
FPS = 12


def _label(job):
    varied = job.varied or {"job": job.id}
    return ", ".join(f"{k}={v}" for k, v in varied.items())


def contact_sheet(batch, records, path):
    """Write ``path`` (PNG): every job's image in a grid (:func:`convsss.sheets.contact_sheet`), captioned by what
    its axes set; a job without its image is a grey tile captioned with its status."""
    from PIL import Image

    from ..sheets import contact_sheet as sheet

    jobs = list(batch.jobs)
    displays, captions = [], []
    for job in jobs:
        record = records.get(job.id, {})
        png = record.get("outputs", {}).get("png")
        if record.get("status") == "done" and png and Path(png).is_file():
            displays.append(np.asarray(Image.open(png).convert("RGB")))
            captions.append(_label(job))
        else:
            displays.append(np.full((8, 8, 3), 128, dtype=np.uint8))
            captions.append(f"{_label(job)}\n({record.get('status', 'pending')})")
    title = f"{batch.command}: {len(jobs)} jobs" + (f" over {', '.join(batch.axes)}" if batch.axes else "")
    return sheet(path, title, displays, captions, columns=int(np.ceil(np.sqrt(len(jobs)))))


def turntables(batch, records, out):
    """For a batch with an ``orbit_deg`` axis: one animated PNG per combination of the other axes, its frames the
    jobs in order of angle (``OUT/turntable.png``, or ``turntable-<rest>.png``). Returns the paths written."""
    from PIL import Image

    groups = {}
    for job in batch.jobs:
        if "orbit_deg" not in job.varied:
            return []
        rest = tuple((k, v) for k, v in job.varied.items() if k != "orbit_deg")
        groups.setdefault(rest, []).append(job)
    written = []
    for rest, jobs in groups.items():
        frames = []
        for job in sorted(jobs, key=lambda j: float(j.varied["orbit_deg"])):
            record = records.get(job.id, {})
            png = record.get("outputs", {}).get("png")
            if record.get("status") == "done" and png and Path(png).is_file():
                frames.append(Image.open(png).convert("RGB"))
        if not frames:
            continue
        name = "turntable" + "".join(f"-{k}={v}" for k, v in rest) + ".png"
        path = Path(out) / name.replace("/", "_")
        atomic_write(path, lambda tmp, frames=frames: frames[0].save(
            tmp, format="PNG", save_all=True, append_images=frames[1:], duration=int(1000 / FPS), loop=0))
        written.append(path)
    return written
