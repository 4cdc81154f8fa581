"""A denoised image: Intel Open Image Denoise (``pyoidn``, its maintained Python binding) guided by the first-hit albedo
and normal AOVs (:mod:`convsss.pipeline.aovs`), as production renderers denoise their previews.

The denoised image is an extra: ``convsss render --denoise`` writes it beside the raw image (``OUT.denoised.exr`` and
``.png``) and the editor shows it as its preview (a toggle); every accuracy figure, ``compare`` and the stats' numbers
use the raw image. OIDN's ``RT`` filter at high quality, HDR input, the guides prefiltered by OIDN (they carry the
pixel filter's edge noise); on the CPU (Mitsuba's LLVM variants).

The denoiser removes noise that is independent from pixel to pixel: a film's ``box`` filter. Mitsuba's default
``gaussian`` (radius 2 pixels) spreads each sample over its neighbours, and OIDN keeps such correlated noise as
detail (a 10 mm skin1 bunny walked at 256², 4 spp, error per 2x2 block against 256 spp: denoised 0.24x the raw
image's with a box filter, 0.96x with the gaussian). The quick scene renders with a box filter where it is denoised;
a scene file's other filter is warned about (:func:`check_pixel_filter`).

OIDN also clamps a walk's bright outliers, which carry part of its mean: the denoised image read 0.86-0.93 of the
raw one's mean over the object on the noisiest ``bench walk`` scenes. So its brightness is given back locally: times
the ratio of the raw to the denoised image, each blurred by a Gaussian of :data:`KEEP_SIGMA` pixels (the ratio held
to [1/4, 4]); the means then read 0.991-1.001 of the raw's, the error per 2x2 block alike.
"""

import warnings

import numpy as np

from .errors import ConvsssError

#: The AOVs the denoiser reads (the integrator's ``aovs`` names).
GUIDES = ("albedo", "normal")
#: The Gaussian (pixels) over which the denoised image keeps the raw one's brightness.
KEEP_SIGMA = 2.0


def denoise(color, albedo=None, normal=None):
    """``color`` (H, W, 3; linear, HDR) denoised, guided by ``albedo`` (H, W, 3; clipped to [0, 1]) and ``normal``
    (H, W, 3; world space), each optional (a normal needs an albedo, as OIDN asks); returns float64 (H, W, 3).

    Negative or non-finite values (none in a render) are set to 0 first: OIDN reads HDR colours as nonnegative. The
    raw image's brightness is kept over :data:`KEEP_SIGMA` pixels (module doc)."""
    try:
        import pyoidn
    except ImportError:  # a dependency: missing only in a partial install
        raise ConvsssError("denoising needs the pyoidn package (pip install pyoidn)") from None
    if normal is not None and albedo is None:
        raise ConvsssError("the denoiser reads a normal guide only with an albedo guide")

    def plain(image, low, high):
        image = np.asarray(image, dtype=np.float32)[..., :3]
        return np.ascontiguousarray(np.clip(np.nan_to_num(image, nan=0.0, posinf=high, neginf=low), low, high))

    from scipy.ndimage import gaussian_filter

    color = plain(color, 0.0, np.finfo(np.float32).max)
    guides = [plain(albedo, 0.0, 1.0) if albedo is not None else None,
              plain(normal, -1.0, 1.0) if normal is not None else None]
    clean = np.asarray(pyoidn.denoise(color, *guides, hdr=True, quality="high"), dtype=np.float64)
    blur = (KEEP_SIGMA, KEEP_SIGMA, 0.0)
    kept = gaussian_filter(color.astype(np.float64), blur) / np.maximum(gaussian_filter(clean, blur), 1e-30)
    return clean * np.clip(kept, 0.25, 4.0)


class CorrelatedNoiseWarning(UserWarning):
    """The film's reconstruction filter correlates the pixels' noise: the denoiser will remove little of it."""


def check_pixel_filter(sensor):
    """Warn (:class:`CorrelatedNoiseWarning`) when ``sensor``'s film filter spreads samples over several pixels;
    returns whether it is a box filter (or one no wider than a pixel)."""
    rfilter = sensor.film().rfilter()
    if rfilter.radius() <= 0.5 + 1e-6:
        return True
    warnings.warn(CorrelatedNoiseWarning(
        f"the film's filter ({str(rfilter).split('[')[0]}, radius {rfilter.radius():g} pixels) correlates the pixels' "
        "noise, which the denoiser keeps as detail: give the film <rfilter type=\"box\"/> for a denoised image"),
        stacklevel=2)
    return False


def guides_of(film, channels):
    """``(albedo, normal)`` from a film's channels (``channels`` names them, e.g. ``albedo.R`` as
    :meth:`~convsss.pipeline.integrator.ConvsssIntegrator.aov_names` does), each None where absent."""
    def layer(name):
        names = [f"{name}.{c}" for c in ("X", "Y", "Z")] if name == "normal" else [f"{name}.{c}" for c in "RGB"]
        if not all(n in channels for n in names):
            return None
        return np.stack([film[..., channels.index(n)] for n in names], axis=-1)

    return layer("albedo"), layer("normal")
