"""The paper's test cases, regenerated: ``convsss figures`` (Munoz et al. 2011, Figs. 2–6, and beyond).

- :mod:`.specs`: what each figure shows (panels, scenes, parameters) and the quick / full :class:`Settings`;
- :mod:`.scenes`: the figures' scenes, built by :func:`convsss.scene.quick.quick_scene` around bundled meshes;
- :mod:`.render`: panels through the ``convsss`` integrator; the exact-sum and ``volpathmis`` references;
- :mod:`.cache`: references cached on disk by a hash of the scene and the settings;
- :mod:`.sheet`: contact sheets (panels with captions) and plots;
- :mod:`.report`: ``report.md`` (tables, plots, the closing note) and ``figures.json``;
- :mod:`.run`: the whole run.

Example::

    from convsss.figures import QUICK, render_figures
    report = render_figures(["fig2"], QUICK, "out/figures")
"""

from .specs import FIGURES, FULL, QUICK, Settings


def render_figures(names, settings, out, progress=True, scheduler=None, workers=None):
    """Render the figures ``names`` (e.g. ``["fig2", "fig5"]``) with ``settings`` into ``out``; write the report.
    With ``scheduler`` (``tcp://HOST:PORT``) or ``workers`` (a local cluster's processes), the references are first
    rendered on Dask (:func:`.run.prefetch_references`).

    Returns ``(report_path, run)`` where ``run`` is the dict also written to ``out/figures.json``.
    """
    from .report import write_report
    from .run import Runner, prefetch_references

    if scheduler or workers:
        prefetch_references(list(names), settings, out, scheduler, workers, progress)
    run = Runner(settings, out, progress).run(list(names))
    return write_report(out, run), run


__all__ = ["FIGURES", "FULL", "QUICK", "Settings", "render_figures"]
