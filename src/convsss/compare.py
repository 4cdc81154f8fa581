"""Image comparison: error metrics of a test image ``B`` against a reference ``A`` over the object's pixels.

Both images are linear RGB (H, W, 3). The metrics are taken over the *object pixels* only: a given mask (nonzero =
object) or, by default, the pixels where the reference is nonzero in some channel (everything but the background).
An image rendered with the integrator's ``mask`` or ``object`` AOV carries its own mask (:func:`mask_layer`): the
pixels where that channel is positive, the translucent objects without the floors and walls around them.
Per channel ``c``, with ``n`` object pixels and the relative floor ``f_c = 0.01 mean(A_c)`` (which keeps the relative
errors finite where the reference is dark, and scales with the images, so every metric but RMSE and the means is
unchanged when both images are scaled together):

- ``rmse = sqrt(mean((B - A)^2))``, in the images' units;
- ``relmse = mean((B - A)^2 / (A^2 + f^2))``, the relative mean squared error;
- ``mean_rel_error = mean(|B - A| / max(A, f))``;
- ``mean_reference = mean(A)``, ``mean_test = mean(B)``, ``max_reference``, ``max_test``;
- ``mean_ratio = mean(B) / mean(A)`` (1 when the energy agrees; a uniformly scaled B reports its scale).

``flip_mean`` is the mean over the object pixels of the FLIP error map (Andersson et al. 2020, the ``flip-evaluator``
package, LDR mode, 67 pixels per degree) of the two images tone-mapped by *one* operator: Reinhard et al. 2002's
photographic operator (:func:`convsss.image.tonemap`) with key 0.18 on the log-average luminance of the reference's
object pixels, the white point at the brightest pixel of either image, then sRGB encoding.

Block averaging (``block = k > 1``), for noisy references (path tracing): both images are averaged over k x k
blocks (rows and columns past the last whole block are dropped) and so is the mask; a block counts as object when
it lies wholly inside the object, so no background is mixed in. Every metric is then taken on the block images.

The false-colour error image shows the signed relative luminance error ``(Y_B - Y_A) / max(Y_A, f_Y)`` through a
diverging colour map (blue: B darker, white: equal, red: B brighter; saturated at ``± limit``), black off the object.
"""

import numpy as np

from .errors import ConvsssError
from .image import luminance, srgb_encode, tonemap

#: Relative floor: the fraction of the reference's mean below which relative errors stop growing.
FLOOR = 0.01
#: The layers of an image (the integrator's AOVs) that mark its object pixels, in order of preference.
MASK_LAYERS = ("mask", "object")
METRICS = ("rmse", "relmse", "mean_rel_error", "mean_reference", "mean_test", "max_reference", "max_test",
           "mean_ratio")


def object_mask(reference, mask=None):
    """Boolean (H, W) mask of the object pixels: ``mask`` (any channel nonzero) or the nonzero reference pixels.

    Parameters
    ----------
    reference : array_like, shape (H, W, 3)
        Linear RGB; a pixel that is nonzero (or NaN) in some channel is an object pixel.
    mask : array_like, shape (H, W) or (H, W, C), optional
        Nonzero (or NaN) = object, in any channel; used instead of the reference when given.

    Returns
    -------
    numpy.ndarray, shape (H, W), bool
    """
    source = reference if mask is None else np.asarray(mask)
    source = np.nan_to_num(np.asarray(source, dtype=np.float64), nan=1.0)
    return np.any(source != 0, axis=-1) if source.ndim == 3 else source != 0


def mask_layer(layers):
    """The object pixels an image marks itself: ``(name, mask)`` of its first ``mask`` or ``object`` layer (also one
    nested by Mitsuba's ``aov`` integrator, e.g. ``convsss.mask``), or None when it has neither.

    Parameters
    ----------
    layers : dict of str to array_like, shape (H, W, C)
        An image's layers by name (:func:`convsss.image.read_layers`).

    Returns
    -------
    tuple of (str, numpy.ndarray of bool, shape (H, W)) or None
        The layer's name and its pixels whose first channel is positive (covered, at least in part, by a translucent
        object; NaN counts as 0).

    Examples
    --------
    >>> name, mask = mask_layer({"": np.ones((1, 3, 3)), "object": np.array([[[0.0], [0.5], [2.0]]])})
    >>> name, mask.tolist()
    ('object', [[False, True, True]])
    """
    for wanted in MASK_LAYERS:
        for name, values in layers.items():
            if name == wanted or name.endswith("." + wanted):
                values = np.asarray(values, dtype=np.float64)
                return name, np.nan_to_num(values[..., 0] if values.ndim == 3 else values) > 0
    return None


def block_average(image, k):
    """Average (H, W) or (H, W, C) ``image`` over k x k blocks: shape (H // k, W // k[, C]); the remainder is dropped.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C)
        Any numbers (a bool mask averages to the fraction of its pixels that are set).
    k : int
        Block side in pixels, >= 1.

    Returns
    -------
    numpy.ndarray, shape (H // k, W // k) or (H // k, W // k, C), float64
        The block means, in the unit of ``image``.

    Examples
    --------
    >>> block_average(np.arange(16.0).reshape(4, 4), 2)
    array([[ 2.5,  4.5],
           [10.5, 12.5]])
    """
    image = np.asarray(image, dtype=np.float64)
    h, w = image.shape[0] // k, image.shape[1] // k
    blocks = image[:h * k, :w * k].reshape((h, k, w, k) + image.shape[2:])
    return blocks.mean(axis=(1, 3))


def _size(image):
    return f"{image.shape[1]}x{image.shape[0]}"


def prepare(reference, test, mask=None, block=1, labels=("reference", "test")):
    """Check the images, find the object pixels and block-average: returns ``(A, B, object_mask)``.

    ``labels`` name the two images in error messages (e.g. their file names).

    Parameters
    ----------
    reference, test : array_like, shape (H, W, 3)
        Linear RGB of the same size, in the same unit; finite over the object pixels.
    mask : array_like, shape (H, W) or (H, W, C), optional
        The object pixels (see :func:`object_mask`); default: the reference's nonzero pixels.
    block : int
        Block side for block averaging (module docstring), 1 to ``min(H, W)``.
    labels : tuple of str

    Returns
    -------
    A, B : numpy.ndarray, shape (H', W', 3), float64
        The images, block-averaged (``H' = H // block``, ``W' = W // block``).
    object_mask : numpy.ndarray, shape (H', W'), bool
        The object pixels (blocks wholly inside the object); at least one.

    Raises
    ------
    ConvsssError
        On any of the conditions above, in one line.
    """
    a = np.asarray(reference, dtype=np.float64)
    b = np.asarray(test, dtype=np.float64)
    for image, label in ((a, labels[0]), (b, labels[1])):
        if image.ndim != 3 or image.shape[2] != 3:
            raise ConvsssError(f"{label} must be an RGB image of shape (H, W, 3), got {image.shape}")
    if a.shape != b.shape:
        raise ConvsssError(f"images differ in size: {labels[0]} is {_size(a)} pixels, {labels[1]} is {_size(b)}")
    if mask is not None and np.shape(mask)[:2] != a.shape[:2]:
        raise ConvsssError(f"the mask is {_size(np.asarray(mask))} pixels but the images are {_size(a)}")
    inside = object_mask(a, mask)
    if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
        raise ConvsssError(f"block={block!r} is not allowed: it must be an integer >= 1")
    if block > min(a.shape[:2]):
        raise ConvsssError(f"block={block} is larger than the {_size(a)} images")
    if not np.any(inside):
        raise ConvsssError("no object pixels: the mask is empty" if mask is not None
                           else f"no object pixels: {labels[0]} is zero everywhere")
    for image, label in ((a, labels[0]), (b, labels[1])):
        bad = int(np.sum(~np.all(np.isfinite(image[inside]), axis=-1)))
        if bad:
            raise ConvsssError(f"{label} has {bad} object pixels with NaN or infinite values")
    if block > 1:
        inside = block_average(inside, block) >= 1.0
        if not np.any(inside):
            raise ConvsssError(f"no {block}x{block} block lies wholly inside the object: choose a smaller block")
        a, b = block_average(a, block), block_average(b, block)
    return a, b, inside


def relative_floor(a, inside):
    """``f_c = FLOOR * mean(A_c)`` over the object, per channel; a black channel borrows the mean of all channels.

    Parameters
    ----------
    a : numpy.ndarray, shape (H, W, 3)
        The (prepared) reference, linear RGB.
    inside : numpy.ndarray, shape (H, W), bool
        The object pixels.

    Returns
    -------
    numpy.ndarray, shape (3,), float64
        The floor per channel, in the unit of ``a``.

    Raises
    ------
    ConvsssError
        When the reference is black in every channel over the object.
    """
    mean = a[inside].mean(axis=0)
    if not np.any(mean > 0):
        raise ConvsssError("the reference is black over the object: relative errors are undefined")
    return FLOOR * np.where(mean > 0, mean, mean.mean())


def metrics(a, b, inside):
    """Per channel metrics (see the module docstring) of prepared images; returns a dict of (3,) arrays.

    Parameters
    ----------
    a, b : numpy.ndarray, shape (H, W, 3)
        Reference and test image from :func:`prepare`, linear RGB in one unit.
    inside : numpy.ndarray, shape (H, W), bool
        The object pixels.

    Returns
    -------
    dict of numpy.ndarray, shape (3,), float64
        Every name of :data:`METRICS`: ``rmse`` and the means and maxima in the images' unit, ``relmse`` and
        ``mean_rel_error`` and ``mean_ratio`` dimensionless (``mean_ratio`` NaN where the reference's channel
        mean is 0).
    """
    a_obj, b_obj = a[inside], b[inside]
    floor = relative_floor(a, inside)
    diff = b_obj - a_obj
    mean_a, mean_b = a_obj.mean(axis=0), b_obj.mean(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(mean_a > 0, mean_b / mean_a, np.nan)
    return {"rmse": np.sqrt(np.mean(diff**2, axis=0)),
            "relmse": np.mean(diff**2 / (a_obj**2 + floor**2), axis=0),
            "mean_rel_error": np.mean(np.abs(diff) / np.maximum(a_obj, floor), axis=0),
            "mean_reference": mean_a, "mean_test": mean_b,
            "max_reference": a_obj.max(axis=0), "max_test": b_obj.max(axis=0),
            "mean_ratio": ratio}


def tonemap_pair(a, b, inside):
    """Both images through one Reinhard operator (keyed on the reference's object pixels), sRGB-encoded in [0, 1].

    The two images are tone-mapped side by side as one picture, with the log-average taken over the reference's
    object pixels only, so they share the scale and the white point.

    Parameters
    ----------
    a, b : numpy.ndarray, shape (H, W, 3)
        Reference and test image, linear RGB in one unit.
    inside : numpy.ndarray, shape (H, W), bool
        The reference's object pixels.

    Returns
    -------
    tuple of two numpy.ndarray, shape (H, W, 3), float32
        The sRGB-encoded display values (8-bit steps divided by 255) of ``a`` and ``b``.
    """
    pair = np.concatenate([a, b], axis=1)
    keyed = np.concatenate([inside, np.zeros_like(inside)], axis=1)
    display = srgb_encode(tonemap(pair, "reinhard", mask=keyed)).astype(np.float32) / 255.0
    return display[:, :a.shape[1]], display[:, a.shape[1]:]


def flip_map(a, b, inside):
    """The FLIP error map (H, W) in [0, 1] of the tone-mapped pair (LDR FLIP, default 67 pixels per degree).

    Parameters
    ----------
    a, b : numpy.ndarray, shape (H, W, 3)
        Reference and test image, linear RGB in one unit (tone-mapped by :func:`tonemap_pair`).
    inside : numpy.ndarray, shape (H, W), bool
        The reference's object pixels, which key the tone mapping.

    Returns
    -------
    numpy.ndarray, shape (H, W), float64
        The FLIP error per pixel (dimensionless; over every pixel, not only the object's).
    """
    import flip_evaluator

    ldr_a, ldr_b = tonemap_pair(a, b, inside)
    error, _, _ = flip_evaluator.evaluate(np.ascontiguousarray(ldr_a), np.ascontiguousarray(ldr_b), "LDR",
                                          inputsRGB=True, applyMagma=False, computeMeanError=False)
    return np.asarray(error, dtype=np.float64).reshape(a.shape[:2])


def compare(reference, test, mask=None, block=1, labels=("reference", "test")):
    """All metrics of ``test`` against ``reference`` (linear RGB, same size) over the object pixels.

    Returns a dict: ``pixels`` (object pixels, or blocks), ``block``, ``relative_floor`` and every name in
    :data:`METRICS` as RGB 3-lists of floats (NaN where undefined), plus the scalar ``flip_mean``.

    Parameters
    ----------
    reference, test : array_like, shape (H, W, 3)
        Linear RGB in one unit (e.g. radiance, as rendered).
    mask, block, labels
        As in :func:`prepare`.

    Returns
    -------
    dict
        Lists of 3 floats in the images' unit for ``relative_floor``, ``rmse`` and the means and maxima;
        dimensionless for ``relmse``, ``mean_rel_error``, ``mean_ratio`` and the float ``flip_mean``; ints
        ``pixels`` and ``block``.

    Examples
    --------
    >>> a = np.ones((8, 8, 3))
    >>> compare(a, 2 * a)["mean_ratio"]
    [2.0, 2.0, 2.0]
    """
    a, b, inside = prepare(reference, test, mask, block, labels)
    result = {"pixels": int(inside.sum()), "block": int(block),
              "relative_floor": relative_floor(a, inside).tolist()}
    result.update({name: np.asarray(value, dtype=np.float64).tolist() for name, value in metrics(a, b, inside).items()})
    result["flip_mean"] = float(np.mean(flip_map(a, b, inside)[inside]))
    return result


def _srgb_decode(encoded):
    """sRGB-encoded [0, 1] to linear [0, 1] (the inverse of the sRGB transfer curve)."""
    return np.where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055) ** 2.4)


def error_image(reference, test, mask=None, block=1, limit=0.2, labels=("reference", "test")):
    """False-colour signed relative luminance error (see the module docstring) as *linear* RGB (H', W', 3).

    ``limit`` (> 0) is the relative error shown fully saturated (0.2: ±20 %). Write it with
    ``convsss.image.write_png(path, image, method="none")``.

    Parameters
    ----------
    reference, test : array_like, shape (H, W, 3)
        Linear RGB in one unit.
    mask, block, labels
        As in :func:`prepare`.
    limit : float
        Relative error (a fraction) at which the colour map saturates.

    Returns
    -------
    numpy.ndarray, shape (H', W', 3), float64
        Linear RGB in [0, 1], black off the object (``H' = H // block``, ``W' = W // block``).
    """
    from matplotlib import colormaps

    if not np.isfinite(limit) or limit <= 0:
        raise ConvsssError(f"limit={limit!r} is not allowed: the colour scale's limit must be > 0")
    a, b, inside = prepare(reference, test, mask, block, labels)
    y_a, y_b = luminance(a), luminance(b)
    floor = FLOOR * float(np.mean(y_a[inside]))
    relative = np.where(inside, (y_b - y_a) / np.maximum(y_a, max(floor, np.finfo(float).tiny)), 0.0)
    colours = colormaps["RdBu_r"](0.5 + 0.5 * np.clip(relative / limit, -1.0, 1.0))[..., :3]
    return np.where(inside[..., None], _srgb_decode(colours), 0.0)
