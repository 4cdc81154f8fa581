"""Profiles drawn as ``r R_d(r)`` on log axes: one panel per material or file, one colour per channel, one line style
per model (``convsss profile plot``, the material editor's plot)."""

import numpy as np

#: Line style per model of a panel, colour per RGB channel.
STYLES = ("-", "--", "-.", ":")
COLOURS = ("tab:red", "tab:green", "tab:blue")


def plot_profiles(panels, path, panel_size=(4.6, 3.6), dpi=100):
    """Write a PNG of ``r R_d(r)`` for every panel.

    Parameters
    ----------
    panels : list of (str, list of (str, Profile))
        Per panel, its title and the ``(label, profile)`` pairs it draws.
    path : str, path-like or binary file object
        Where the PNG goes (matplotlib's ``savefig`` target).
    panel_size : (float, float)
        Inches per panel; at most 3 panels a row.
    dpi : int
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    columns = min(3, len(panels))
    rows = (len(panels) + columns - 1) // columns
    figure = Figure(figsize=(panel_size[0] * columns, panel_size[1] * rows), layout="constrained")
    axes = np.atleast_1d(figure.subplots(rows, columns, squeeze=False)).ravel()
    for ax, (title, profiles) in zip(axes, panels):
        reach = max(float(np.max(p.radius_energy(1e-4))) for _, p in profiles)
        core = min(float(np.min(p.radius_energy(1 - 1e-3))) for _, p in profiles)
        r = np.geomspace(max(core, reach * 1e-5), reach, 400)
        top = max(float(np.max(r[:, None] * p(r))) for _, p in profiles)
        if not top > 0.0:  # a medium that does not scatter reflects nothing diffusely: no curve to draw on log axes
            ax.set(title=title, xlabel="r  [mm]", ylabel="r R_d(r)  [1/mm]")
            ax.text(0.5, 0.5, "R_d = 0: the medium does not scatter", ha="center", va="center",
                    transform=ax.transAxes)
            continue
        for k, (model, p) in enumerate(profiles):
            values = p(r)
            for c in range(3):
                ax.plot(r, r * values[:, c], STYLES[k % 4], color=COLOURS[c], lw=1.2,
                        label=model if c == 0 else None)
        ax.set(xscale="log", yscale="log", title=title, xlabel="r  [mm]", ylabel="r R_d(r)  [1/mm]")
        ax.set_ylim(top * 1e-5, top * 2)
        ax.legend(fontsize=7)
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    figure.savefig(path, format="png", dpi=dpi)
