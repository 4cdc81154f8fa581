"""Running the figures: references first (cached), then every panel, errors, contact sheets, the report.

Per figure ``F`` under ``out``: ``F/<panel>.exr`` (linear) and ``F/<panel>.png`` (tone-mapped with the panel's group),
``F/F.png`` (the contact sheet). Then ``report.md``, ``figures.json`` (every number of the report) and the plots;
references live in ``out/cache`` (:mod:`.cache`).

Errors (:func:`convsss.compare.compare`, over the object's pixels = the reference's non-black pixels): against the
exact sum pixel by pixel (same scene, resolution, spp and seed, so the same camera rays: only the transport
differs), and against volpathmis after ``block`` x ``block`` averaging (its noise). Summaries: ``mre`` is the mean
relative error and ``ratio`` the mean(test)/mean(reference), both averaged over RGB; ``rel_l2`` is
``sqrt(relative MSE)`` averaged over RGB; ``flip`` the mean FLIP error.
"""

import time
import warnings
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..compare import compare
from ..errors import ConvsssError
from .cache import ReferenceCache
from .render import PROFILE_COLUMNS, exact_reference, panel_params, path_traced_reference, render_convsss
from .scenes import load
from .specs import FIGURES

#: Relative error shown fully saturated in the error maps.
ERROR_LIMIT = 0.25


def error_summary(reference, test, block=1):
    """Mean relative error, relative L2, mean ratio (RGB-averaged), FLIP and the per-channel values.

    Parameters
    ----------
    reference, test : numpy.ndarray, shape (H, W, 3)
        Linear RGB in one unit (:func:`convsss.compare.compare`).
    block : int
        Block averaging (1: pixel by pixel).

    Returns
    -------
    dict
        ``mre``, ``rel_l2`` (the square root of ``relmse``), ``ratio``, ``flip``: floats, dimensionless;
        ``block``, ``pixels``: ints; ``per_channel``: RGB lists of ``mean_rel_error``, ``relmse``, ``mean_ratio``.
    """
    result = compare(reference, test, block=block)
    return {"mre": float(np.mean(result["mean_rel_error"])), "rel_l2": float(np.mean(np.sqrt(result["relmse"]))),
            "ratio": float(np.mean(result["mean_ratio"])), "flip": float(result["flip_mean"]),
            "block": block, "pixels": result["pixels"],
            "per_channel": {k: result[k] for k in ("mean_rel_error", "relmse", "mean_ratio")}}


def select(only):
    """Figure names from ``--only`` (comma-separated, ``fig2`` or ``2``), in the paper's order."""
    if not only:
        return list(FIGURES)
    names = []
    for item in str(only).split(","):
        item = item.strip().lower()
        if not item:
            continue
        name = item if item.startswith("fig") else f"fig{item}"
        if name not in FIGURES:
            raise ConvsssError(f"unknown figure {item!r} in --only: choose from {', '.join(FIGURES)}")
        names.append(name)
    if not names:
        raise ConvsssError(f"--only {only!r} names no figure: choose from {', '.join(FIGURES)}")
    return [n for n in FIGURES if n in names]


def reference_calls(names):
    """Every reference the figures ``names`` read, once each: ``(kind, spec, overrides)`` with ``kind`` ``exact`` or
    ``volpathmis`` (:meth:`Runner.references` reads the same)."""
    calls = {}
    for name in names:
        figure = FIGURES[name]()
        for spec in figure.scenes():
            calls[("exact", spec, "")] = ("exact", spec, None)
            if figure.versus_pt:
                calls[("volpathmis", spec, "")] = ("volpathmis", spec, None)
                for column, overrides in PROFILE_COLUMNS.items():
                    calls[("exact", spec, column)] = ("exact", spec, overrides)
    return list(calls.values())


def compute_reference(kind, spec, overrides, settings, cache_root):
    """One reference rendered into the cache at ``cache_root`` (in a worker: :func:`prefetch_references`); returns
    ``(kind, scene description, whether it was cached already)``."""
    s, cache = settings, ReferenceCache(cache_root)
    if kind == "exact":
        _, _, hit = exact_reference(spec, cache, s.error_resolution, s.error_spp, s.seed, overrides=overrides)
    else:
        _, _, hit = path_traced_reference(spec, cache, s.error_resolution, s.pt_spp, s.pass_spp, s.seed,
                                          progress=False)
    return kind, spec.describe(), hit


def prefetch_references(names, settings, out, scheduler=None, workers=None, progress=True):
    """The figures' references rendered on Dask workers into ``out/cache`` (:func:`convsss.batch.runner.on_cluster`),
    so that the run that follows reads them all from the cache. The panels are not: their seconds are part of the
    figures, measured one at a time on this machine. Returns how many were rendered; a one-line error names the
    first that failed."""
    from ..batch.runner import on_cluster

    calls = [(kind, spec, overrides, settings, str(Path(out).resolve() / "cache"))
             for kind, spec, overrides in reference_calls(names)]
    results = on_cluster(compute_reference, calls, scheduler, workers, progress=progress, desc="references")
    for (kind, spec, *_), result in zip(calls, results):
        if isinstance(result, Exception):
            raise ConvsssError(f"the {kind} reference of {spec.describe()} failed on the cluster: {result}")
    return sum(not hit for _, _, hit in results)


class Runner:
    """Renders figures with :class:`~convsss.figures.specs.Settings` into ``out``; see the module docstring."""

    def __init__(self, settings, out, progress=True):
        self.settings = settings
        self.out = Path(out)
        self.progress = progress
        self.cache = ReferenceCache(self.out / "cache")
        self._scenes = {}
        self.bar = None

    # --- helpers ------------------------------------------------------------------------------------------------------
    def scene(self, spec, resolution, spp):
        key = (spec, resolution, spp)
        if key not in self._scenes:
            self._scenes[key] = load(spec, resolution, resolution, spp)
        return self._scenes[key]

    def _status(self, text):
        if self.bar is not None:
            self.bar.set_postfix_str(text[:60])

    def warm_up(self, spec):
        """Compile Dr.Jit and numba kernels on a tiny render of each transport, so no panel pays for it."""
        start = time.perf_counter()
        scene = load(spec, 32, 32, 1)
        for method in ("convolution", "hierarchical", "exact"):
            render_convsss(scene, panel_params(method, {}), 1, self.settings.seed)
        return time.perf_counter() - start

    def references(self, figure):
        """``{spec: {"exact": (image, meta, hit), "volpathmis": ...}}`` for the figure's scenes.

        Parameters
        ----------
        figure : Figure

        Returns
        -------
        dict
            Per :class:`~convsss.figures.scenes.SceneSpec`, the ``exact`` reference and, for a figure compared with
            path tracing, the ``volpathmis`` one and under ``profiles`` the exact sum of each column of
            :data:`~convsss.figures.render.PROFILE_COLUMNS`: each ``(image, meta, hit)`` with ``image`` linear RGB of
            shape (error_resolution, error_resolution, 3), float64 (:func:`~convsss.figures.render.exact_reference`).
        """
        s = self.settings
        refs = {}
        for spec in figure.scenes():
            self._status(f"exact reference: {spec.material} {spec.mesh}")
            refs[spec] = {"exact": exact_reference(spec, self.cache, s.error_resolution, s.error_spp, s.seed)}
            if figure.versus_pt:
                self._status(f"volpathmis reference: {spec.material} {spec.mesh}")
                refs[spec]["volpathmis"] = path_traced_reference(spec, self.cache, s.error_resolution, s.pt_spp,
                                                                 s.pass_spp, s.seed, self.progress)
                refs[spec]["profiles"] = {}
                for name, overrides in PROFILE_COLUMNS.items():
                    self._status(f"exact sum, {name}: {spec.material} {spec.mesh}")
                    refs[spec]["profiles"][name] = exact_reference(spec, self.cache, s.error_resolution, s.error_spp,
                                                                   s.seed, overrides=overrides)
        return refs

    def profile_rows(self, refs):
        """Per scene of a figure compared with path tracing: ``{"scene", "columns": {column: error summary}}``, each
        column of :data:`~convsss.figures.render.PROFILE_COLUMNS` against ``volpathmis`` (:func:`error_summary`)."""
        return [{"scene": spec.describe(),
                 "columns": {name: error_summary(ref["volpathmis"][0], image, self.settings.block)
                             for name, (image, _, _) in ref["profiles"].items()}}
                for spec, ref in refs.items() if "profiles" in ref]

    # --- one panel ----------------------------------------------------------------------------------------------------
    def panel(self, figure, panel, refs):
        """Render one panel (or take its reference) and measure its errors.

        Parameters
        ----------
        figure : Figure
        panel : Panel
        refs : dict
            The references of the panel's scene: one entry of :meth:`references`.

        Returns
        -------
        image : numpy.ndarray, shape (H, W, 3), float64
            The panel's linear RGB, at the panel resolution (a reference's at the error resolution).
        record : dict
            The panel's row of ``figures.json``.
        test : numpy.ndarray, shape (H', W', 3), float64
            The image the errors were measured on: ``image``, or the separate render at the error resolution.
        """
        s = self.settings
        exact, exact_meta, exact_hit = refs["exact"]
        pt = refs.get("volpathmis")
        record = {"figure": figure.key, "panel": panel.key, "title": panel.title, "method": panel.method,
                  "parameters": panel.parameters_text(), "params": dict(panel.params), "scene": panel.scene.to_dict(),
                  "group": panel.group, "vs_exact": None, "vs_pt": None, "cached": None, "c": None}
        if panel.method == "exact":
            image = exact
            record.update(resolution=s.error_resolution, spp=s.error_spp, cached=exact_hit,
                          seconds=exact_meta.get("render_seconds", exact_meta["seconds"]),
                          sss_seconds=exact_meta.get("sss_seconds"), samples=exact_meta.get("samples"))
            if pt is not None:
                record["vs_pt"] = error_summary(pt[0], exact, s.block)
            return image, record, image
        if panel.method == "volpathmis":
            image, meta, hit = pt
            record.update(resolution=s.error_resolution, spp=s.pt_spp, cached=hit, seconds=meta["seconds"],
                          sss_seconds=None)
            return image, record, image
        params = panel_params(panel.method, panel.params)
        progress = (lambda stage: self._status(f"{panel.key}: {stage}")) if self.progress else None
        scene = self.scene(panel.scene, s.resolution, s.spp)
        image, summary = render_convsss(scene, params, s.spp, s.seed, progress)
        record.update(resolution=s.resolution, spp=s.spp, seconds=summary["seconds"],
                      sss_seconds=summary["sss_seconds"], samples=summary["samples"], c=summary["c"],
                      pairs_per_layer=summary["pairs_per_layer"], layers_computed=summary["layers_computed"],
                      mean_free_paths=summary["mean_free_paths"], stage_seconds=summary["stage_seconds"],
                      transport_stats=summary["transport_stats"])
        if "epsilon" in summary["transport_stats"]:
            record["parameters"] += f", ε = {summary['transport_stats']['epsilon']:g}"
        if s.separate_error_renders:
            self._status(f"{panel.key}: {s.error_resolution}² render for errors")
            small = self.scene(panel.scene, s.error_resolution, s.error_spp)
            test, small_summary = render_convsss(small, params, s.error_spp, s.seed)
            record["error_render"] = {"resolution": s.error_resolution, "spp": s.error_spp,
                                      "seconds": small_summary["seconds"], "sss_seconds": small_summary["sss_seconds"],
                                      "c": small_summary["c"]}
        else:
            test = image
        record["vs_exact"] = error_summary(exact, test)
        if pt is not None:
            record["vs_pt"] = error_summary(pt[0], test, s.block)
        return image, record, test

    # --- one figure ---------------------------------------------------------------------------------------------------
    def figure(self, name):
        from ..compare import error_image
        from ..image import srgb_encode, write_exr
        from ..sheets import contact_sheet
        from .report import caption, error_caption
        from .sheet import tonemap_groups

        figure = FIGURES[name]()
        start = time.perf_counter()
        folder = self.out / name
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            refs = self.references(figure)
            images, records, error_maps = [], [], []
            for panel in figure.panels:
                self._status(panel.key)
                image, record, test = self.panel(figure, panel, refs[panel.scene])
                record["exr"] = str(write_exr(folder / f"{panel.key}.exr", image).relative_to(self.out))
                images.append(image)
                records.append(record)
                if record["vs_exact"] is not None:
                    exact = refs[panel.scene]["exact"][0]
                    error_maps.append((srgb_encode(error_image(exact, test, limit=ERROR_LIMIT)), record))
                if self.bar is not None:
                    self.bar.update()
            self._scenes.clear()
        anchors = {}
        for panel in figure.panels:  # each group is shown at the exposure of its scene's exact sum
            anchors.setdefault(panel.group, refs[panel.scene]["exact"][0])
        displays = tonemap_groups(images, [p.group for p in figure.panels], anchors)
        for panel, display, record in zip(figure.panels, displays, records):
            record["png"] = str(_write_display(folder / f"{panel.key}.png", display).relative_to(self.out))
        s = self.settings
        footer = (f"{s.name} run: panels {s.resolution}² at {s.spp} spp; errors on {s.error_resolution}² renders "
                  f"at {s.error_spp} spp (volpathmis {s.pt_spp} spp, {s.block}×{s.block} blocks). "
                  "err: mean relative error vs the exact sum; ratio: mean(image)/mean(reference).")
        sheet = contact_sheet(folder / f"{name}.png", figure.title, displays, [caption(r) for r in records],
                              figure.columns, footer)
        errors_sheet = None
        if error_maps:
            errors_sheet = contact_sheet(
                folder / f"{name}-errors.png", f"{figure.title}: relative error against the exact sum",
                [m for m, _ in error_maps], [error_caption(r) for _, r in error_maps],
                sum(not p.is_reference for p in figure.panels[:figure.columns]) or figure.columns,
                f"Signed relative luminance error (panel - exact) / exact on the {s.error_resolution}² renders: "
                f"blue darker, red brighter, saturated at ±{100 * ERROR_LIMIT:g} %; black: not the object.")
            errors_sheet = str(errors_sheet.relative_to(self.out))
        messages = sorted({str(w.message) for w in caught})
        return {"key": name, "title": figure.title, "paper": figure.paper, "notes": figure.notes,
                "columns": figure.columns, "versus_pt": figure.versus_pt, "panels": records,
                "sheet": str(sheet.relative_to(self.out)), "errors_sheet": errors_sheet,
                "profiles": self.profile_rows(refs),
                "seconds": time.perf_counter() - start, "warnings": messages}

    def run(self, names):
        """Render the figures ``names``; returns the run's dict (what ``figures.json`` holds)."""
        from tqdm import tqdm

        from .specs import FIGURES as builders

        start = time.perf_counter()
        total = sum(len(builders[n]().panels) for n in names)
        self.bar = tqdm(total=total, desc="figures", unit="panel", disable=not self.progress,
                        bar_format="{desc}: {n_fmt}/{total_fmt} panels |{bar:24}| {elapsed}<{remaining} {postfix}")
        try:
            self._status("warming up (kernel compilation)")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                warm = self.warm_up(builders[names[0]]().panels[0].scene)
            figures = []
            for name in names:
                self.bar.set_description_str(f"figures ({name})")
                figures.append(self.figure(name))
        finally:
            self.bar.close()
            self.bar = None
        return {"settings": asdict(self.settings), "figures": figures, "warm_up_seconds": warm,
                "cache": {"hits": self.cache.hits, "misses": self.cache.misses, "root": "cache"},
                "seconds": time.perf_counter() - start}


def _write_display(path, display):
    """Write an sRGB uint8 image as PNG, atomically."""
    from ..files import atomic_write
    from ..image import display_png_writer

    return atomic_write(path, display_png_writer(display))
