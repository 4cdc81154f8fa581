"""``convsss materials``: the table of measured presets."""

import json

import click
import numpy as np

from .main import cli


def _triple(values, fmt):
    return "/".join("inf" if not np.isfinite(v) else format(v, fmt) for v in values)


@cli.command()
@click.option("--json", "as_json", is_flag=True,
              help="Print a JSON list of objects with the keys name, sigma_s_prime, sigma_a, eta, total_reflectance, "
                   "mfp_mm, diffusion_length_mm (RGB 3-lists; infinity as null) instead of a table.")
def materials(as_json):
    """List the measured material presets (Jensen et al. 2001, Narasimhan et al. 2006).

    Per preset and RGB channel: reduced scattering sigma_s' and absorption sigma_a (1/mm), relative index eta,
    total diffuse reflectance of the classic dipole, reduced mean free path 1/sigma_t' and diffusion length
    1/sigma_tr (mm; inf without absorption). Names are looked up ignoring case, spaces and punctuation.
    """
    from ..materials import catalog
    from ..profiles.models import color_of

    totals = [color_of(m, "dipole") for m in catalog()]
    rows = [{**m.summary(), "total_reflectance": t.tolist()} for m, t in zip(catalog(), totals)]
    if as_json:
        click.echo(json.dumps(rows, indent=1))
        return
    header = f"{'name':<28} {'sigma_s_prime 1/mm':<22} {'sigma_a 1/mm':<24} {'eta':>4}  {'R_total':<17} " \
             f"{'mfp mm':<19} {'diffusion length mm':<20}"
    click.echo(header)
    for m, total in zip(catalog(), totals):
        click.echo(f"{m.name:<28} {_triple(m.sigma_s_prime, '.4g'):<22} {_triple(m.sigma_a, '.4g'):<24} "
                   f"{m.eta:>4.2f}  {_triple(total, '.3f'):<17} {_triple(m.mfp_mm, '.3g'):<19} "
                   f"{_triple(m.diffusion_length_mm, '.3g'):<20}")
