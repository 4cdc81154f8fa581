"""``convsss compare``: error metrics of one image against a reference, over the object's pixels."""

import json
from pathlib import Path

import click

from ..files import check_outputs, json_ready, write_files
from .main import cli

_ROWS = (("rmse", "RMSE"), ("relmse", "relative MSE"), ("mean_rel_error", "mean relative error"),
         ("mean_reference", "mean A"), ("mean_test", "mean B"), ("mean_ratio", "mean B / mean A"),
         ("max_reference", "max A"), ("max_test", "max B"))


@cli.command()
@click.argument("reference", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("test", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--mask", "mask_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Image (PNG, EXR) of the object: pixels nonzero in any channel are compared (e.g. the OUT-mask.png "
                   "of `convsss render --mask`). Default: a mask channel of the images (--mask-channels), else the "
                   "pixels where REFERENCE is nonzero (everything but a black background).")
@click.option("--mask-channels/--no-mask-channels", "use_channels", default=True, show_default=True,
              help="Compare the pixels that a 'mask' or 'object' channel (render --aovs mask or --mask) of REFERENCE, "
                   "else of TEST, marks as a translucent object (positive values), not floors and walls; "
                   "--no-mask-channels: the nonzero pixels of REFERENCE. --mask overrides both.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Write a false-colour PNG of the signed relative luminance error (B - A) / A: blue where TEST is "
                   "darker, white where equal, red where brighter, saturated at +-R (--range); black off the "
                   "object; one pixel per block with --block. Beside it, OUT-reference.png and OUT-test.png: A and "
                   "B tone-mapped alike (one Reinhard operator, key 0.18 on A's object pixels).")
@click.option("--range", "limit", type=float, default=0.2, show_default=True, metavar="R",
              help="Relative error shown fully saturated in the --output image (0.2 = +-20 %).")
@click.option("--block", type=click.IntRange(min=1), default=1, show_default=True, metavar="K",
              help="Average K x K pixel blocks of both images (and the mask) before every metric, for noisy "
                   "references; only blocks wholly inside the object count.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object instead of a table: reference, test, mask (the --mask path or null), "
                   "mask_source {kind: image, channel or nonzero; image; channel}, size [W, H], block, pixels, "
                   "relative_floor, and per channel (RGB 3-lists; null where undefined) rmse, relmse, "
                   "mean_rel_error, mean_reference, mean_test, max_reference, max_test, mean_ratio; plus the "
                   "scalar flip_mean, error_image (the --output path or null) and images (the two tone-mapped "
                   "inputs' paths, or null).")
def compare(reference, test, mask_path, use_channels, output, limit, block, as_json):
    """Compare TEST (B) against REFERENCE (A), two linear images (EXR; PNG is decoded to linear) of one size.

    Per RGB channel, over the object pixels: RMSE; relative MSE mean((B-A)^2 / (A^2 + f^2)); mean relative error
    mean(|B-A| / max(A, f)), with f = 1 % of the reference's mean; the means and maxima; and mean(B) / mean(A)
    (a uniformly scaled B reports its scale). FLIP: the mean over the object of the LDR FLIP error of both images
    tone-mapped with one Reinhard operator (key 0.18 on the reference's log-average, shared white point, sRGB).

    The object pixels: --mask, else the mask (or object) channel of REFERENCE or TEST, else the nonzero pixels of
    REFERENCE; the output says which.
    """
    from ..compare import compare as compare_images
    from ..compare import error_image, mask_layer, object_mask
    from ..image import png_writer, read_image, read_layers

    pictures = None
    if output is not None:
        pictures = [output.with_name(f"{output.stem}-{side}.png") for side in ("reference", "test")]
        check_outputs([output, *pictures], [p for p in (reference, test, mask_path) if p is not None])
    layers = [read_layers(reference), read_layers(test)]
    a, b = layers[0][""], layers[1][""]
    mask, source = None, {"kind": "nonzero", "image": str(reference), "channel": None}
    if mask_path is not None:
        mask, source = read_image(mask_path), {"kind": "image", "image": str(mask_path), "channel": None}
    elif use_channels:
        for path, image_layers in zip((reference, test), layers):
            found = mask_layer(image_layers)
            if found is not None:
                mask, source = found[1], {"kind": "channel", "image": str(path), "channel": found[0]}
                break
    labels = (reference.name, test.name)
    result = compare_images(a, b, mask, block, labels)
    if output is not None:
        inside = object_mask(a, mask)  # one operator for both: keyed on A's object pixels, A's white point
        write_files({output: png_writer(error_image(a, b, mask, block, limit, labels), method="none"),
                     pictures[0]: png_writer(a, mask=inside),
                     pictures[1]: png_writer(b, mask=inside, anchor=a)})
    if as_json:
        report = {"reference": str(reference), "test": str(test),
                  "mask": None if mask_path is None else str(mask_path), "mask_source": source,
                  "size": [a.shape[1], a.shape[0]], **result,
                  "error_image": None if output is None else str(output),
                  "images": None if pictures is None else [str(p) for p in pictures]}
        click.echo(json.dumps(json_ready(report), indent=1))
        return
    unit = f"{block}x{block} blocks" if block > 1 else "pixels"
    click.echo(f"A (reference): {reference}  {a.shape[1]}x{a.shape[0]}, {result['pixels']} object {unit}")
    click.echo(f"B (test):      {test}")
    click.echo(f"object {unit}: " + {"image": f"the mask {source['image']}",
                                        "channel": f"the {source['channel']!r} channel of {source['image']}",
                                        "nonzero": f"the nonzero pixels of {source['image']}"}[source["kind"]])
    click.echo(f"{'':<22}{'R':>12}{'G':>12}{'B':>12}")
    for key, label in _ROWS:
        click.echo(f"{label:<22}" + "".join(f"{v:>12.5g}" for v in result[key]))
    click.echo(f"{'FLIP mean':<22}{result['flip_mean']:>12.5g}")
    if output is not None:
        click.echo(f"error image: {output} (relative luminance error, +-{limit:g}); A and B exposed alike: "
                   f"{pictures[0]}, {pictures[1]}")
