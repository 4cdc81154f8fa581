"""Pictures of many images and plots, saved as PNG whole or not at all: a contact sheet of panels with captions
(the paper's figures, a batch's jobs) and a matplotlib plot."""

import textwrap

PANEL_INCHES = 2.4
CAPTION_LINE_INCHES = 0.15


def contact_sheet(path, title, displays, captions, columns, footer=""):
    """Save a grid of ``displays`` (uint8 RGB) with ``captions`` (multi-line strings) under each; returns ``path``.

    Parameters
    ----------
    path : str or Path
        The PNG to write.
    title : str
    displays : list of numpy.ndarray, shape (H, W, 3), uint8
        sRGB-encoded panels (e.g. from :func:`tonemap_groups`).
    captions : list of str
        One per panel.
    columns : int
        Panels per row (at most the number of panels).
    footer : str

    Returns
    -------
    Path
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from .files import atomic_write

    n = len(displays)
    columns = max(1, min(columns, n))
    rows = -(-n // columns)
    lines = max(c.count("\n") + 1 for c in captions) if captions else 0
    cell_h = PANEL_INCHES + (lines + 0.6) * CAPTION_LINE_INCHES
    footer = textwrap.fill(footer, width=int(columns * PANEL_INCHES * 19)) if footer else ""
    title = textwrap.fill(title, width=int(columns * PANEL_INCHES * 9))
    top = 0.25 + 0.2 * (title.count("\n") + 1)
    bottom = 0.15 + 0.12 * (footer.count("\n") + 1) if footer else 0.1
    fig = plt.figure(figsize=(columns * PANEL_INCHES, rows * cell_h + top + bottom))
    height = rows * cell_h + top + bottom
    for k, (display, caption) in enumerate(zip(displays, captions)):
        r, c = divmod(k, columns)
        y0 = height - top - (r * cell_h) - PANEL_INCHES
        ax = fig.add_axes([c / columns, y0 / height, 1 / columns, PANEL_INCHES / height])
        ax.imshow(display, interpolation="lanczos" if display.shape[0] > 300 else "nearest")
        ax.set_axis_off()
        ax.text(0.5, -0.02, caption, transform=ax.transAxes, ha="center", va="top", fontsize=6.5,
                family="DejaVu Sans", linespacing=1.25)
    fig.text(0.5, 1 - 0.12 / height, title, ha="center", va="top", fontsize=10, weight="bold")
    if footer:
        fig.text(0.5, 0.08 / height, footer, ha="center", va="bottom", fontsize=6, color="0.3")
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=160, facecolor="white"))
    finally:
        plt.close(fig)


def plot(path, draw, size=(6.0, 3.0)):
    """A matplotlib plot made by ``draw(figure)``, saved atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from .files import atomic_write

    fig = plt.figure(figsize=size)
    try:
        draw(fig)
        fig.tight_layout()
        return atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=130))
    finally:
        plt.close(fig)
