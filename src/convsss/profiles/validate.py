"""Every profile model against the path-traced semi-infinite slab (:mod:`convsss.profiles.slab`) of a material.

Per channel, the tally's radial histogram (the measured ``R(r)`` in the normalization of Eq. 1) and its total are
compared with each model's bin averages (``energy_within`` at the bin edges over the annulus area, so a steep
profile is compared like for like) and its ``total_reflectance``; the total is also compared with the exact
half-space total (:func:`~convsss.profiles.models.exact_total`), which every model renders with under
``profile_total exact`` (the default). Tallies are cached on disk by
``(albedo', eta, photons, seed)``: every preset with the same reduced albedo and index shares one.
"""

import hashlib
import json
from pathlib import Path

import numpy as np

from ..files import json_ready, write_files
from . import CHANNELS
from .models import MODEL_TITLES, PROFILE_MODELS, exact_total, model_profile
from .slab import slab_tally

#: Bump when a change makes cached tallies wrong.
SLAB_FORMAT = 1
#: Bins whose tally is noisier than this (relative standard error) are left out of the profile error.
NOISE_LIMIT = 0.1
#: The key and title of the exact half-space total among the models of :func:`summary` (a total, no profile).
EXACT = "exact total"
EXACT_TITLE = "Exact half-space total (every model's total under profile_total exact, the default)"


def _key(albedo, eta, photons, seed):
    text = json.dumps([SLAB_FORMAT, float(albedo).hex(), float(eta).hex(), int(photons), int(seed)])
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def cached_tally(albedo, eta, photons, seed, cache=None):
    """:func:`~convsss.profiles.slab.slab_tally`, read from or written to the folder ``cache`` (None: no cache)."""
    path = None if cache is None else Path(cache) / f"slab-{_key(albedo, eta, photons, seed)}.npz"
    if path is not None and path.is_file():
        with np.load(path) as data:
            return {k: (data[k] if data[k].ndim else data[k].item()) for k in data.files}
    tally = slab_tally(albedo, eta, photons, seed)
    if path is not None:
        write_files({path: lambda tmp: np.savez(tmp, **tally)})  # tmp ends in .npz
    return tally


def validate_material(material, models=tuple(PROFILE_MODELS), photons=1 << 19, seed=0, cache=None):
    """Each model of ``material`` against its slab tally.

    Parameters
    ----------
    material : Material
    models : sequence of str
        Model names (:data:`~convsss.profiles.PROFILE_MODELS`).
    photons, seed : int
        Of the tally (per channel).
    cache : str or Path, optional
        Folder of cached tallies.

    Returns
    -------
    dict
        ``name``, ``albedo_prime`` (3,), ``eta``; ``slab``: per channel ``r_mm`` (bin centres), ``profile``,
        ``stderr`` (1/mm^2), and ``total`` (3,), ``total_stderr`` (3,); ``models``: per model ``total`` (3,),
        ``total_error`` (3,) relative to the slab, ``profile`` (per channel bin averages), ``profile_error`` (3,):
        the mean of ``|model/slab - 1|`` over the bins weighted by their share of the slab's energy (bins noisier than
        :data:`NOISE_LIMIT` left out); ``exact``: ``total`` and ``total_error`` of the exact half-space total.
    """
    tallies = [cached_tally(a, material.eta, photons, seed, cache) for a in material.albedo_prime]
    slab = {"r_mm": [], "edges_mm": [], "profile": [], "stderr": [], "energy": []}
    for c, t in enumerate(tallies):
        s = material.sigma_t_prime[c]
        edges = t["edges"] / s
        slab["edges_mm"].append(edges)
        slab["r_mm"].append(np.sqrt(np.maximum(edges[:-1], edges[1] / 2) * edges[1:]))
        slab["profile"].append(t["profile"] * s * s)
        slab["stderr"].append(t["stderr"] * s * s)
        slab["energy"].append(t["profile"] * np.pi * np.diff(t["edges"] ** 2))
    slab["total"] = np.array([t["total"] for t in tallies])
    slab["total_stderr"] = np.array([t["total_stderr"] for t in tallies])
    out = {"name": material.name, "albedo_prime": material.albedo_prime, "eta": material.eta, "photons": photons,
           "slab": slab, "models": {}}
    exact = exact_total(material.albedo_prime, material.eta)
    out["exact"] = {"total": exact, "total_error": _relative(exact, slab["total"])}
    for model in models:
        profile = model_profile(model, material)
        total = profile.total_reflectance
        per_bin, errors = [], []
        for c in range(3):
            edges = slab["edges_mm"][c]
            energy = profile.energy_within(edges)[:, c]
            average = np.diff(energy) / (np.pi * np.diff(edges**2))
            per_bin.append(average)
            measured, noise = slab["profile"][c], slab["stderr"][c]
            ok = (measured > 0) & (noise < NOISE_LIMIT * np.maximum(measured, 1e-300))
            weight = slab["energy"][c] * ok
            rel = np.where(ok, average / np.where(ok, measured, 1.0) - 1.0, 0.0)
            errors.append(float(np.sum(weight * np.abs(rel)) / max(np.sum(weight), 1e-300)))
        out["models"][model] = {"total": total, "total_error": _relative(total, slab["total"]), "profile": per_bin,
                                "profile_error": np.array(errors)}
    return out


def _relative(total, measured):
    """``total / measured - 1`` per channel; NaN where nothing is measured (0/0: a channel that scatters nothing)."""
    return np.divide(total, measured, out=np.full(3, np.nan), where=measured > 0) - 1.0


def plot_validation(result, path):
    """``R(r) r`` of the slab and each model on log axes, and each model's relative error, per channel (a PNG)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    figure = Figure(figsize=(13.0, 6.5), layout="constrained")
    axes = figure.subplots(2, 3, sharex="col", height_ratios=[2, 1])
    slab = result["slab"]
    for c in range(3):
        top, bottom = axes[0, c], axes[1, c]
        r, measured, noise = slab["r_mm"][c], slab["profile"][c], slab["stderr"][c]
        shown = measured > 0
        top.errorbar(r[shown], (r * measured)[shown], yerr=(r * noise)[shown], fmt=".", color="black", ms=3,
                     label=f"slab, path traced ({slab['total'][c]:.4f}; exact half-space "
                     f"{result['exact']['total'][c]:.4f})", zorder=3)
        for model, m in result["models"].items():
            line, = top.plot(r, r * m["profile"][c], label=f"{model} ({m['total'][c]:.4f}, "
                                                             f"{100 * m['total_error'][c]:+.1f} %)")
            good = shown & (noise < NOISE_LIMIT * np.maximum(measured, 1e-300))
            bottom.plot(r[good], m["profile"][c][good] / measured[good] - 1.0, color=line.get_color())
        top.set(xscale="log", yscale="log", title=f"{result['name']} {CHANNELS[c]}: alpha' = "
                f"{result['albedo_prime'][c]:.4g}, eta = {result['eta']:g}", ylabel="r R(r)  [1/mm]")
        positive = (r * measured)[shown]
        if len(positive):
            top.set_ylim(max(positive.min(), positive.max() * 1e-6) * 0.5, positive.max() * 3)
        top.legend(fontsize=7, title="model (total, error)", title_fontsize=7)
        bottom.axhline(0.0, color="black", lw=0.5)
        bottom.set(xscale="log", ylim=(-0.5, 0.5), xlabel="r  [mm]", ylabel="model / slab - 1")
    figure.savefig(path, format="png", dpi=100)


def validation_table(results, models):
    """A Markdown table: per material and channel, the slab's total reflectance, the relative error of the exact
    half-space total and each model's."""
    head = ("| material | ch | alpha' | slab total | exact total err | "
            + " | ".join(f"{m} total err | {m} profile err" for m in models))
    lines = [head + " |", "|" + "---|" * (5 + 2 * len(models))]
    for res in results:
        for c in range(3):
            row = [res["name"], CHANNELS[c], f"{res['albedo_prime'][c]:.4f}",
                   f"{res['slab']['total'][c]:.4f} ± {res['slab']['total_stderr'][c]:.4f}",
                   f"{100 * res['exact']['total_error'][c]:+.2f} %"]
            for m in models:
                row += [f"{100 * res['models'][m]['total_error'][c]:+.1f} %",
                        f"{100 * res['models'][m]['profile_error'][c]:.1f} %"]
            lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def summary(results, models, albedo_limit=0.5):
    """Per model, and for the exact half-space total (:data:`EXACT`, no profile error): the worst and mean |total
    error| over channels with ``alpha' > albedo_limit`` and over the rest."""
    out = {}
    for m in [EXACT, *models]:
        of = [r["exact"] if m == EXACT else r["models"][m] for r in results]
        # a channel that scatters nothing has no total to err on (0/0): left out
        thick = [abs(o["total_error"][c]) for r, o in zip(results, of) for c in range(3)
                 if r["albedo_prime"][c] > albedo_limit and np.isfinite(o["total_error"][c])]
        thin = [abs(o["total_error"][c]) for r, o in zip(results, of) for c in range(3)
                if r["albedo_prime"][c] <= albedo_limit and np.isfinite(o["total_error"][c])]
        prof = [] if m == EXACT else [o["profile_error"][c] for r, o in zip(results, of) for c in range(3)
                                      if r["albedo_prime"][c] > albedo_limit]
        out[m] = {"title": EXACT_TITLE if m == EXACT else MODEL_TITLES[m],
                  "thick_channels": len(thick), "thick_max": max(thick, default=np.nan),
                  "thick_mean": float(np.mean(thick)) if thick else np.nan,
                  "thick_within_2pct": int(np.sum(np.array(thick) <= 0.02)),
                  "thick_profile_error_mean": float(np.mean(prof)) if prof else np.nan,
                  "thin_channels": len(thin), "thin_max": max(thin, default=np.nan),
                  "thin_mean": float(np.mean(thin)) if thin else np.nan}
    return json_ready(out)
