"""A batch's SPEC (TOML): the scenes, the axes swept, and the jobs they make, checked before anything runs.

::

    command = "render"            # or "reference": what every job runs (default render)

    [scene]                       # what every job renders: the command's own options, as in its --help
    mesh = "bunny"                #   (a scene file: file = "scene.xml", relative to the SPEC)
    size_mm = 40
    width = 64
    height = 64
    spp = 4

    [axes]                        # swept: every combination of their values is a job
    material = ["wholemilk", "marble"]
    seed = [1, 2]
    # a value may be a table of several options at once:
    # colour = [{color = "0.8,0.5,0.4", mfp_mm = 2}, {material = "skin1"}]

Instead of ``[axes]``, ``[[jobs]]`` tables list the jobs one by one (each a table of options over ``[scene]``).
An option is any of the command's (``convsss render --help``: ``material``, ``color``, ``mfp_mm``, ``profile``,
``transport``, ``light_scale``, ``orbit_deg``, ``width``, ``spp``, ``seed``, every integrator parameter, ...),
written with underscores or dashes; ``true`` is a flag. ``file`` and ``mesh`` are relative to the SPEC. The
runner sets ``-o``, ``--stats`` and ``--progress``.

The options are the command's own: a SPEC is read with the commands' parsers (``parsers``, their ``click.Command``
by name, which :mod:`convsss.cli` gives), so a value is converted and checked as the command line would, and this
package imports nothing of the command line.
"""

import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ConvsssError

#: What a job may run, and the options the runner sets itself.
COMMANDS = ("render", "reference")
RESERVED = ("output", "stats_path", "progress", "scene_file")
#: The SPEC's top-level keys.
TOP_KEYS = ("command", "scene", "axes", "jobs")
#: The default bound on the number of jobs (``--max-jobs``).
MAX_JOBS = 10_000


class SpecError(ConvsssError):
    """A SPEC's problems, one line each (``problems``), all found before any job runs."""

    def __init__(self, problems):
        self.problems = list(dict.fromkeys(problems))
        super().__init__("\n".join(self.problems))


@dataclass(frozen=True)
class Job:
    """One job: ``id`` (its output folder's name, stable for the same SPEC), ``options`` (the command's options by
    their Python names, the base's with the job's own over them) and ``varied`` (what the axes set, for labels)."""

    id: str
    options: dict
    varied: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Batch:
    """A checked SPEC: the ``command`` every job runs and its ``parser`` (a ``click.Command``), the ``jobs``, and the
    ``axes`` names swept (for sheets)."""

    command: str
    parser: object = field(compare=False, repr=False)
    jobs: tuple = ()
    axes: tuple = ()


def option_names(parser):
    """The options a job of the command ``parser`` may set: ``{python name: click parameter}``."""
    return {p.name: p for p in parser.params if p.name not in RESERVED}


def _slug(value):
    text = re.sub(r"[^A-Za-z0-9.+-]+", "_", str(value)).strip("_")
    return text[:24] or "x"


def _job_id(index, varied):
    parts = [f"{_slug(k)}={_slug(v)}" for k, v in varied.items()]
    return "-".join([f"{index:04d}", *parts])[:120]


def _flatten(name, value):
    """An axis value as options: a table sets several at once, anything else sets the option ``name``."""
    return dict(value) if isinstance(value, dict) else {name: value}


def read_spec(path, parsers, max_jobs=MAX_JOBS):
    """The :class:`Batch` of the SPEC at ``path``; a :class:`ConvsssError` listing every problem, one per line,
    before anything runs (unknown keys and options, empty axes, too many jobs, values the command refuses)."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib

    path = Path(path)
    try:
        spec = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ConvsssError(f"SPEC {str(path)!r} does not exist") from None
    except tomllib.TOMLDecodeError as error:
        raise ConvsssError(f"SPEC {str(path)!r} is not valid TOML: {error}") from None
    return batch_from_spec(spec, parsers, path.parent, max_jobs)


def batch_from_spec(spec, parsers, folder=".", max_jobs=MAX_JOBS):
    """:func:`read_spec` of a parsed SPEC (a dict), ``parsers`` the commands' ``click.Command`` by name; relative
    scene files are taken from ``folder``."""
    problems = [f"unknown key {k!r} (allowed: {', '.join(TOP_KEYS)})" for k in spec if k not in TOP_KEYS]
    command = spec.get("command", "render")
    if command not in COMMANDS:
        raise SpecError([f"command {command!r} is not allowed: give one of {', '.join(COMMANDS)}"])
    parser = parsers[command]
    allowed = option_names(parser)
    base = _options(spec.get("scene", {}), allowed, "[scene]", problems)

    axes, listed = spec.get("axes", {}), spec.get("jobs", [])
    if axes and listed:
        problems.append("give [axes] or [[jobs]], not both")
    if not isinstance(axes, dict) or not isinstance(listed, list):
        raise SpecError(["[axes] must be a table of lists and [[jobs]] an array of tables"])
    for name, values in axes.items():
        if not isinstance(values, list) or not values:
            problems.append(f"axis {name!r} has no values: give a non-empty list")
        elif not all(isinstance(v, dict) for v in values):
            _options({name: values[0]}, allowed, f"axis {name!r}", problems)
    if problems:
        raise SpecError(problems)
    count = 1
    for values in axes.values():
        count *= len(values)
    count = len(listed) if listed else count
    if count > max_jobs:
        raise SpecError([f"the SPEC makes {count} jobs, more than --max-jobs {max_jobs}"])
    if listed:
        combos = [(options, options) for options in (_options(job, allowed, f"job {i}", problems)
                                                     for i, job in enumerate(listed))]
    else:
        combos = []
        for chosen in itertools.product(*axes.values()):
            varied, options = {}, {}
            for name, value in zip(axes, chosen):
                flat = _options(_flatten(name, value), allowed, f"axis {name!r}", problems)
                options.update(flat)
                varied.update(flat)
            combos.append((varied, options))
    jobs = []
    for index, (varied, options) in enumerate(combos):
        job = Job(_job_id(index, varied), _files({**base, **options}, folder), varied)
        problems += [f"job {job.id}: {p}" for p in check_job(parser, job)]
        jobs.append(job)
    problems += _scene_problems(jobs)
    if problems:
        raise SpecError(problems)
    return Batch(command, parser, tuple(jobs), tuple(axes))


def _scene_problems(jobs):
    """Each distinct scene file loaded once (Mitsuba's parser): one line per job whose scene fails to load."""
    files = {job.options["scene_file"] for job in jobs if "scene_file" in job.options}
    files = {f for f in files if Path(f).is_file()}
    if not files:
        return []
    from ..pipeline.integrator import register
    from ..scene.loading import load_scene

    register()
    failed = {}
    for file in sorted(files):
        try:
            load_scene(file)
        except (ConvsssError, RuntimeError) as error:
            failed[file] = " ".join(str(error).split())[:200]
    return [f"job {job.id}: the scene {job.options['scene_file']!r} does not load: {failed[job.options['scene_file']]}"
            for job in jobs if job.options.get("scene_file") in failed]


def _files(options, folder):
    """``file`` as the command's scene file, and it and ``mesh`` relative to the SPEC's ``folder``, made absolute
    (the workers run elsewhere)."""
    options = dict(options)
    if "file" in options:
        options["scene_file"] = options.pop("file")
    for name in ("scene_file", "mesh"):
        if name in options and options[name] != "bunny":
            options[name] = str((Path(folder) / options[name]).resolve())
    return options


def _options(table, allowed, where, problems):
    """``table``'s keys as the command's Python option names (dashes allowed), with unknown ones reported."""
    out = {}
    for key, value in table.items():
        name = key.replace("-", "_")
        if name not in allowed and name != "file":
            problems.append(f"{where}: unknown option {key!r}")
            continue
        out[name] = value
    return out


def arguments(parser, options):
    """The command line (a list of str, without the command's name) of a job's ``options`` for ``parser``."""
    allowed = option_names(parser)
    args = [str(options["scene_file"])] if "scene_file" in options else []
    for name, value in options.items():
        if name == "scene_file":
            continue
        param = allowed[name]
        flag = param.opts[0]
        if getattr(param, "is_flag", False) and not param.secondary_opts:
            if value:
                args.append(flag)
        elif getattr(param, "is_flag", False):
            args.append(flag if value else param.secondary_opts[0])
        else:
            args += [flag, str(value)]
    return args


def keywords(parser, options):
    """A job's ``options`` as the keyword arguments of the library function its command calls
    (:func:`~convsss.outputs.render_to_files` or :func:`~convsss.outputs.reference_to_files`, ``source`` a
    :class:`~convsss.scene.source.SceneSource`), each value converted and checked as the command's option would be."""
    from ..scene.source import FIELDS, SceneSource

    params = parser.make_context(parser.name, [*arguments(parser, options), "-o", "x"]).params
    keywords = {k: v for k, v in params.items() if k not in (*FIELDS, *RESERVED)}
    if "write_mask" in keywords:
        keywords["mask"] = keywords.pop("write_mask")
    return {"source": SceneSource(**{k: params[k] for k in FIELDS}), **keywords}


def check_job(parser, job):
    """What ``command`` would refuse in ``job``'s options (one line each): values its options reject, a scene
    file that does not exist, a mesh or a material that is not there. Nothing is loaded or rendered."""
    import click

    from ..scene.source import FIELDS, SceneSource

    problems = []
    try:
        parser.make_context(parser.name, [*arguments(parser, job.options), "-o", "x"],
                                       resilient_parsing=False)
    except click.UsageError as error:
        problems.append(" ".join(error.format_message().split()))
    options = job.options
    if "scene_file" in options and not Path(options["scene_file"]).is_file():
        problems.append(f"the scene file {options['scene_file']!r} does not exist")
    mesh = options.get("mesh")
    if mesh and mesh != "bunny" and not Path(mesh).is_file():
        problems.append(f"the mesh {mesh!r} does not exist")
    try:
        SceneSource(**{k: v for k, v in options.items() if k in FIELDS}).check()
    except ConvsssError as error:
        problems.append(str(error))
    return problems
