"""``convsss batch``: many renders at once, on Dask distributed (docs/guide/batch.md).

A SPEC (:mod:`.spec`) names the scene and the axes swept; every combination is a job, what ``convsss render`` (or
``reference``) runs (:mod:`convsss.outputs`) in a worker process with its own output folder (:mod:`.runner`); the
batch's folder gets a manifest kept current, a contact sheet and turntables (:mod:`.sheet`). A second run resumes.
"""

from .runner import run_batch, run_job
from .sheet import contact_sheet, turntables
from .spec import Batch, Job, SpecError, batch_from_spec, read_spec

__all__ = ["Batch", "Job", "SpecError", "batch_from_spec", "contact_sheet", "read_spec", "run_batch", "run_job",
           "turntables"]
