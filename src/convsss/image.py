"""Images in and out: linear EXR and tone-mapped PNG through Mitsuba's own bitmap I/O, written whole or not at all.

Tone mapping (for display only; EXRs stay linear):

- ``reinhard``: Reinhard et al. 2002's photographic operator (the paper's choice): scale to ``key / L_w`` with the
  log-average luminance ``L_w = exp(mean(log(delta + L)))``, then ``L_d = L (1 + L / L_white^2) / (1 + L)``
  with ``L_white`` the largest scaled luminance; colours keep their ratios;
- ``exposure``: ``rgb * 2^exposure``, clipped;
- ``none``: clipped as is.

Then sRGB encoding and 8 bits. The key must be finite and positive, the exposure finite and within
:data:`MAX_STOPS` (:func:`check_tonemap`).
"""

import math
from pathlib import Path

import numpy as np

from .errors import ConvsssError
from .files import atomic_write

TONEMAPS = ("reinhard", "exposure", "none")
#: The largest exposure either way, in stops (2^100: far past any image's range, short of float overflow).
MAX_STOPS = 100
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def luminance(rgb):
    """Rec. 709 luminance of linear RGB (..., 3).

    Parameters
    ----------
    rgb : array_like, shape (..., C), C >= 3
        Linear RGB in any radiometric unit; channels past the third are ignored.

    Returns
    -------
    numpy.ndarray, shape (...), float64
        ``0.2126 R + 0.7152 G + 0.0722 B``, in the unit of ``rgb``.

    Examples
    --------
    >>> float(luminance([1.0, 1.0, 1.0]))
    1.0
    """
    return np.asarray(rgb, dtype=np.float64)[..., :3] @ _LUMINANCE


def check_tonemap(method="reinhard", key=0.18, exposure=0.0):
    """Raise :class:`~convsss.errors.ConvsssError` unless the tone mapping's settings are usable.

    Parameters
    ----------
    method : str
        One of :data:`TONEMAPS`.
    key : float
        Reinhard's key value: finite and > 0.
    exposure : float
        Stops: finite.

    Examples
    --------
    >>> check_tonemap("reinhard", key=0.0)
    Traceback (most recent call last):
    ...
    convsss.errors.ConvsssError: key=0.0 is not allowed: the tone mapping's key must be finite and > 0
    """
    if method not in TONEMAPS:
        raise ConvsssError(f"unknown tone mapping {method!r}: choose one of {', '.join(TONEMAPS)}")
    if not (math.isfinite(key) and key > 0):
        raise ConvsssError(f"key={key!r} is not allowed: the tone mapping's key must be finite and > 0")
    if not math.isfinite(exposure) or abs(exposure) > MAX_STOPS:
        raise ConvsssError(f"exposure={exposure!r} is not allowed: the exposure must be finite, at most {MAX_STOPS} "
                           "stops either way")


def tonemap(rgb, method="reinhard", key=0.18, exposure=0.0, mask=None, anchor=None):
    """Linear RGB (H, W, 3) to display values in [0, 1] (before sRGB encoding).

    ``mask`` (H, W) restricts the log-average of the Reinhard operator to the pixels that matter (e.g. the object);
    ``anchor``, another linear image, keys the operator instead of ``rgb`` (a render exposed like its reference).
    Bad settings raise :class:`~convsss.errors.ConvsssError` (:func:`check_tonemap`).

    Parameters
    ----------
    rgb : array_like, shape (H, W, C), C >= 3
        Linear RGB in any radiometric unit; NaN and negative values count as 0, channels past the third are ignored.
    method, key, exposure
        As in :func:`check_tonemap`; ``exposure`` (stops) scales the image by ``2^exposure`` first, for every
        method but ``none``.
    mask : array_like of bool, shape (H, W), optional
        The pixels whose log-average luminance keys the ``reinhard`` operator (default, or when empty: the non-black
        pixels), in ``anchor`` when it is given.
    anchor : array_like, shape (H', W', C), C >= 3, optional
        The linear image (in ``rgb``'s unit, any size) whose log-average luminance and maximum fix the ``reinhard``
        operator's scale and white point, after the same ``2^exposure`` (default: ``rgb`` itself).

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), float64
        Linear display values in [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> dim, bright = np.full((2, 2, 3), 0.1), np.full((2, 2, 3), 10.0)
    >>> float(tonemap(dim)[0, 0, 0]) == float(tonemap(bright)[0, 0, 0])      # each keyed on itself
    True
    >>> bool(tonemap(dim, anchor=bright)[0, 0, 0] < tonemap(bright)[0, 0, 0])   # exposed like ``bright``
    True
    """
    check_tonemap(method, key, exposure)
    rgb = np.maximum(np.nan_to_num(np.asarray(rgb, dtype=np.float64)[..., :3]), 0.0)
    if method == "none":
        return np.clip(rgb, 0.0, 1.0)
    if method == "exposure":
        return np.clip(rgb * 2.0 ** float(exposure), 0.0, 1.0)
    exposed = rgb * 2.0 ** float(exposure)
    keyed = exposed if anchor is None else np.asarray(anchor, dtype=np.float64) * 2.0 ** float(exposure)
    return Reinhard(keyed, key, mask)(exposed)


class Reinhard:
    """Reinhard et al. 2002's photographic operator with its scale and white point fixed by an ``anchor`` image.

    Scale ``key / L_w`` with the log-average luminance ``L_w = exp(mean(log(1e-6 + L)))`` over ``mask`` (default: the
    anchor's non-black pixels), white point ``L_white`` = the largest scaled luminance; then
    ``L_d = L (1 + L / L_white^2) / (1 + L)`` with colours keeping their ratios. One operator applied to several
    images exposes them alike.

    Parameters
    ----------
    anchor : array_like, shape (H, W, C), C >= 3
        The linear RGB image (any radiometric unit) that fixes the scale and the white point; NaN and negative values
        count as 0.
    key : float
        The key value (> 0).
    mask : array_like of bool, shape (H, W), optional
        The anchor's pixels to take the log-average over (default, or when empty: its non-black pixels).
    """

    def __init__(self, anchor, key=0.18, mask=None):
        lum = luminance(np.maximum(np.nan_to_num(np.asarray(anchor, dtype=np.float64)[..., :3]), 0.0))
        region = lum[mask] if mask is not None and np.any(mask) else lum[lum > 0]
        self.scale = key / float(np.exp(np.mean(np.log(1e-6 + region)))) if region.size else key
        self.white = max(float(np.max(lum, initial=0.0)) * self.scale, 1e-12)

    def __call__(self, rgb):
        """Linear RGB (H, W, 3) to display values in [0, 1] (before sRGB encoding).

        Parameters
        ----------
        rgb : array_like, shape (..., C), C >= 3
            Linear RGB in the anchor's unit; NaN and negative values count as 0, channels past the third are
            ignored.

        Returns
        -------
        numpy.ndarray, shape (..., 3), float64
            Linear display values in [0, 1].
        """
        rgb = np.maximum(np.nan_to_num(np.asarray(rgb, dtype=np.float64)[..., :3]), 0.0)
        lum = luminance(rgb)
        scaled = self.scale * lum
        display = scaled * (1.0 + scaled / self.white**2) / (1.0 + scaled)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(lum > 0, display / lum, 0.0)
        return np.clip(rgb * ratio[..., None], 0.0, 1.0)


def srgb_encode(display):
    """Linear [0, 1] to the sRGB transfer curve, then to uint8.

    Parameters
    ----------
    display : array_like, any shape
        Linear display values; clipped to [0, 1].

    Returns
    -------
    numpy.ndarray, the shape of ``display``, uint8
        sRGB-encoded values in 0..255, rounded to the nearest.

    Examples
    --------
    >>> srgb_encode(np.array([0.0, 0.5, 1.0]))
    array([  0, 188, 255], dtype=uint8)
    """
    x = np.clip(display, 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(encoded * 255.0).astype(np.uint8)


def _bitmap(array):
    from .backend import load_mitsuba

    mi = load_mitsuba()
    return mi, mi.Bitmap(np.ascontiguousarray(array))


def display_png_writer(pixels):
    """``write(path)``, saving sRGB uint8 pixels (H, W, 3) as a PNG: one entry of :func:`convsss.files.write_files`.

    Parameters
    ----------
    pixels : array_like, shape (H, W, 3)
        sRGB-encoded display values, converted to uint8 (0..255).

    Returns
    -------
    callable
        ``write(path)``, which saves the PNG at ``path``.
    """
    mi, bitmap = _bitmap(np.asarray(pixels, dtype=np.uint8))
    return lambda path: bitmap.write(path, mi.Bitmap.FileFormat.PNG)


def exr_writer(rgb, channels=None):
    """``write(path)``, saving linear RGB (H, W, 3) as a float32 OpenEXR file: one entry of
    :func:`convsss.files.write_files`, which writes several files together.

    Parameters
    ----------
    rgb : array_like, shape (H, W, C), C >= 3
        Linear RGB in any radiometric unit, stored as float32; without ``channels``, channels past the third are
        dropped.
    channels : sequence of str, optional
        One name per channel of ``rgb`` (``R``, ``G``, ``B`` first), to store every channel: e.g. the integrator's
        AOVs ``exitance.R``, ``mask.Y`` (Mitsuba's layer.channel names, which EXR viewers show as layers).

    Returns
    -------
    callable
        ``write(path)``, which saves the EXR at ``path``.

    Raises
    ------
    ConvsssError
        When ``rgb`` is not of shape (H, W, C) with C >= 3, or ``channels`` does not name its channels, RGB first.
    """
    rgb = np.asarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] < 3:
        raise ConvsssError(f"an RGB image must have shape (H, W, 3), got {rgb.shape}")
    if channels is None or list(channels) == ["R", "G", "B"]:
        mi, bitmap = _bitmap(rgb[..., :3])
    else:
        channels = [str(c) for c in channels]
        if len(channels) != rgb.shape[2] or channels[:3] != ["R", "G", "B"] or len(set(channels)) != len(channels):
            raise ConvsssError(f"{rgb.shape[2]} image channels need as many distinct names, R, G, B first; got "
                               f"{', '.join(channels)}")
        from .backend import load_mitsuba

        mi = load_mitsuba()
        bitmap = mi.Bitmap(np.ascontiguousarray(rgb), mi.Bitmap.PixelFormat.MultiChannel, channels)
    return lambda path: bitmap.write(path, mi.Bitmap.FileFormat.OpenEXR)


def mask_png_writer(coverage):
    """``write(path)``, saving a mask (H, W) in [0, 1] (e.g. the ``mask`` AOV: the translucent objects' coverage)
    as an 8-bit grey PNG, black = 0, white = 1, sRGB-encoded as every PNG (so :func:`read_image` reads the coverage
    back, to 8 bits): one entry of :func:`convsss.files.write_files`.

    Parameters
    ----------
    coverage : array_like, shape (H, W)
        Values clipped to [0, 1]; NaN counts as 0.

    Returns
    -------
    callable
        ``write(path)``, which saves the PNG at ``path``.
    """
    grey = srgb_encode(np.nan_to_num(np.asarray(coverage, dtype=np.float64)))
    from .backend import load_mitsuba

    mi = load_mitsuba()
    bitmap = mi.Bitmap(np.ascontiguousarray(grey), mi.Bitmap.PixelFormat.Y)
    return lambda path: bitmap.write(path, mi.Bitmap.FileFormat.PNG)


def png_writer(rgb, method="reinhard", key=0.18, exposure=0.0, mask=None, anchor=None):
    """``write(path)``, saving linear RGB (H, W, 3) tone-mapped (:func:`tonemap`) as an 8-bit sRGB PNG: one entry of
    :func:`convsss.files.write_files`.

    Parameters
    ----------
    rgb : array_like, shape (H, W, C), C >= 3
        Linear RGB in any radiometric unit.
    method, key, exposure, mask, anchor
        As in :func:`tonemap` (``mask``: bool, shape (H, W)).

    Returns
    -------
    callable
        ``write(path)``, which saves the PNG at ``path``.
    """
    return display_png_writer(srgb_encode(tonemap(rgb, method, key, exposure, mask, anchor)))


def write_exr(path, rgb):
    """Write linear RGB (H, W, 3) as a float32 OpenEXR file, atomically. Returns the path.

    Parameters
    ----------
    path : str or Path
        The file to write.
    rgb : array_like, shape (H, W, C), C >= 3
        Linear RGB in any radiometric unit, stored as float32; channels past the third are dropped.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write(path, exr_writer(rgb))


def write_png(path, rgb, method="reinhard", key=0.18, exposure=0.0, mask=None, anchor=None):
    """Tone-map linear RGB (H, W, 3) and write an 8-bit sRGB PNG, atomically. Returns the path.

    Parameters
    ----------
    path : str or Path
        The file to write.
    rgb : array_like, shape (H, W, C), C >= 3
        Linear RGB in any radiometric unit.
    method, key, exposure, mask, anchor
        As in :func:`tonemap` (``mask``: bool, shape (H, W)).

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write(path, png_writer(rgb, method, key, exposure, mask, anchor))


def _open(path):
    path = Path(path)
    if not path.is_file():
        raise ConvsssError(f"image {str(path)!r} does not exist")
    from .backend import load_mitsuba

    mi = load_mitsuba()
    try:
        return mi, mi.Bitmap(str(path))
    except Exception as error:
        raise ConvsssError(f"cannot read image {str(path)!r}: {error}") from None


def _linear(mi, bitmap, pixel_format):
    """``bitmap`` as float64 (H, W, C) in ``pixel_format``, sRGB-decoded if it is encoded; a multi-channel layer (EXR
    data, linear) as stored."""
    if pixel_format == mi.Bitmap.PixelFormat.MultiChannel:
        return np.array(bitmap, dtype=np.float64).reshape(bitmap.height(), bitmap.width(), -1)
    converted = bitmap.convert(pixel_format, mi.Struct.Type.Float32, srgb_gamma=False)
    return np.array(converted, dtype=np.float64).reshape(bitmap.height(), bitmap.width(), -1)


def read_image(path):
    """Read an EXR (linear) or PNG/JPEG (sRGB-decoded to linear) image as float64 (H, W, 3).

    Parameters
    ----------
    path : str or Path
        An image file Mitsuba's bitmap reader knows; of an EXR with more channels (AOVs), its R, G, B.

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), float64
        Linear RGB (through float32): as stored for an EXR, in [0, 1] for an 8-bit image; a grey or RGBA image is
        converted to RGB.

    Raises
    ------
    ConvsssError
        When the file does not exist or cannot be read, or has more channels but no R, G, B.
    """
    mi, bitmap = _open(path)
    if bitmap.pixel_format() == mi.Bitmap.PixelFormat.MultiChannel:
        layers = dict(bitmap.split())
        if "<root>" not in layers or layers["<root>"].channel_count() < 3:
            raise ConvsssError(f"image {str(path)!r} has no R, G, B channels (it has "
                               f"{', '.join(f.name for f in bitmap.struct_())})")
        bitmap = layers["<root>"]
    return _linear(mi, bitmap, mi.Bitmap.PixelFormat.RGB)


def read_layers(path):
    """Every layer of an image, by name: ``""`` for the colour (R, G, B as :func:`read_image` reads them) and, for an
    EXR with more channels, each ``layer`` of its ``layer.channel`` names (e.g. ``exitance`` of ``exitance.R``).

    Parameters
    ----------
    path : str or Path
        An image file Mitsuba's bitmap reader knows.

    Returns
    -------
    dict of str to numpy.ndarray, shape (H, W, C), float64
        Linear values; the channels of a layer in the file's order (R, G, B for a colour layer).

    Raises
    ------
    ConvsssError
        When the file does not exist or cannot be read.
    """
    mi, bitmap = _open(path)
    if bitmap.pixel_format() != mi.Bitmap.PixelFormat.MultiChannel:
        return {"": read_image(path)}
    out = {}
    for name, layer in bitmap.split():
        name = "" if name == "<root>" else name
        out[name] = _linear(mi, layer, layer.pixel_format())
    return out
