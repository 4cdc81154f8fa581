"""What each figure shows: the paper's test cases (Munoz et al. 2011, Figs. 2–6) as lists of panels.

A :class:`Panel` is one image: a scene (:class:`~convsss.figures.scenes.SceneSpec`), a method (``convolution``,
``hierarchical``, or a reference: ``exact``, ``volpathmis``) and the integrator parameters that differ from the
defaults (8 layers, ``t`` = 0.1 %, full-resolution layers, the paper's Phong highlights). Panels of one ``group`` are
tone-mapped by one operator, so brightness differences between them are real; a figure of unrelated materials
(the gallery) gives every panel its own group.

Scenes use an index-matched (``null``) boundary wherever a path-traced column or an error against path tracing is
wanted (a point light behind a smooth dielectric is unreachable for a path tracer, docs/architecture.md); the gallery
uses a smooth dielectric with the paper's Phong highlights.
"""

from dataclasses import dataclass, field, replace

from .scenes import SceneSpec

METHODS = ("convolution", "hierarchical", "exact", "volpathmis")
REFERENCES = ("exact", "volpathmis")


@dataclass(frozen=True)
class Settings:
    """How big and how well everything is rendered.

    ``resolution``/``spp``: the panels; ``error_resolution``/``error_spp``: the renders errors are measured on (the
    exact sum costs pixels × samples, so the full run measures errors on smaller renders of the same panels);
    ``pt_spp``: volpathmis samples per pixel (at ``error_resolution``), compared after ``block`` x ``block``
    averaging.
    """

    name: str
    resolution: int
    spp: int
    error_resolution: int
    error_spp: int
    pt_spp: int
    pass_spp: int = 16
    block: int = 4
    seed: int = 0

    def at(self, resolution):
        """These settings with panels of ``resolution`` pixels a side, the errors measured on the panels themselves
        up to 256 pixels and on 256² renders of them above."""
        errors = (resolution, self.spp) if resolution <= 256 else (256, self.error_spp)
        return replace(self, resolution=resolution, error_resolution=errors[0], error_spp=errors[1])

    @property
    def separate_error_renders(self):
        return (self.error_resolution, self.error_spp) != (self.resolution, self.spp)


#: ``--quick``: everything at 128², errors on the panels themselves.
QUICK = Settings("quick", resolution=128, spp=2, error_resolution=128, error_spp=2, pt_spp=64)
#: The paper's 800×800; errors measured on 256² renders of the same panels (exact and volpathmis at 256²).
FULL = Settings("full", resolution=800, spp=8, error_resolution=256, error_spp=2, pt_spp=256, pass_spp=32)


@dataclass(frozen=True)
class Panel:
    key: str
    title: str
    scene: SceneSpec
    method: str = "convolution"
    params: dict = field(default_factory=dict)
    group: str = "all"

    @property
    def is_reference(self):
        return self.method in REFERENCES

    def parameters_text(self):
        """``layers 8 · t 0.1 % · r 1`` for a convolution panel; the method's name otherwise."""
        if self.method == "convolution":
            p = {"layers": 8, "threshold": 0.001, "downsample": 1.0, "correction": "none", **self.params}
            text = f"{p['layers']} layers · t = {100 * p['threshold']:g} % · r = {p['downsample']:g}"
            return text + (" · plane correction" if p["correction"] == "plane" else "")
        return {"hierarchical": "Jensen–Buhler 2002", "exact": "exact sum", "volpathmis": "volpathmis"}[self.method]


@dataclass(frozen=True)
class Figure:
    key: str
    title: str
    paper: str  # the paper's caption, abridged
    panels: tuple
    columns: int
    versus_pt: bool = False
    notes: str = ""

    def scenes(self):
        """The distinct scenes of the figure, in panel order."""
        return list(dict.fromkeys(p.scene for p in self.panels))


MILK_BUNNY = SceneSpec("bunny", "wholemilk", 40.0)


def fig2():
    small, large = SceneSpec("bunny", "wholemilk", 4.0), MILK_BUNNY
    panels = []
    for t in (0.0, 0.001, 0.05):
        for spec, size in ((small, "small"), (large, "large")):
            panels.append(Panel(f"t{100 * t:g}-{size}".replace(".", "_"), f"{spec.size_mm:g} mm bunny", spec,
                                params={"layers": 8, "threshold": t, "downsample": 1.0}, group=size))
    return Figure("fig2", "Fig. 2 — the threshold optimization (paper §5, Eq. 8)",
                  "Wholemilk bunny, 8 layers, no downsampling; left: a bunny ten times smaller; rows: threshold "
                  "t = 0 %, 0.1 %, 5 %; below each image the convolutions per layer c and the seconds.",
                  tuple(panels), columns=2,
                  notes="Small bunny 4 mm, large 40 mm; both framed alike and lit alike (quick_scene scales the "
                        "lights with the object), index-matched boundary.")


def fig3():
    panels = tuple(Panel(f"r{d:g}".replace(".", "_"), f"layer resolution {d:g}", MILK_BUNNY,
                         params={"layers": 8, "downsample": d}) for d in (1.0, 0.5, 0.25))
    return Figure("fig3", "Fig. 3 — layer resolution (paper §5)",
                  "Wholemilk bunny, 8 layers at 800×800; full, half and quarter layer resolution r; seconds.",
                  panels, columns=3, notes="Threshold t = 0.1 % (the paper does not say which it used).")


GALLERY = (("skimmilk", "bunny", 40.0), ("potato", "bust", 60.0), ("apple", "dragon", 50.0),
           ("wholemilk", "bust", 60.0), ("ketchup", "bunny", 40.0), ("marble", "dragon", 50.0),
           ("skin1", "bust", 60.0), ("cream", "bunny", 40.0), ("regular chocolate milk", "dragon", 50.0),
           ("regular soy milk", "bust", 60.0))


def fig4():
    panels = []
    for material, mesh, size in GALLERY:
        spec = SceneSpec(mesh, material, size, "dielectric", 180.0 if mesh == "bust" else 0.0)
        key = material.replace(" ", "-")
        panels.append(Panel(key, f"{material}, {mesh} {size:g} mm", spec, group=key))
    return Figure("fig4", "Fig. 4 — material gallery", "Skimmilk, potato, apple, wholemilk [JMLH01]; wax, ketchup, "
                  "orange juice, soap [MES*11].", tuple(panels), columns=5,
                  notes="Materials of Jensen et al. 2001 (skimmilk, potato, apple, wholemilk, ketchup, marble, skin1, "
                        "cream) and two of Narasimhan et al. 2006 (regular chocolate milk, regular soy milk): the "
                        "[MES*11] media of the paper are not in our tables. Smooth dielectric boundary with the "
                        "paper's Phong highlights; 8 layers, t = 0.1 %, full-resolution layers; each panel "
                        "tone-mapped on its own, as the paper does.")


def fig5():
    panels = [Panel(f"layers{n}", f"{n} layers", MILK_BUNNY, params={"layers": n, "threshold": 0.0})
              for n in (2, 4, 8, 16)]
    panels += [Panel(f"layers{n}-plane", f"{n} layers + plane correction", MILK_BUNNY,
                     params={"layers": n, "threshold": 0.0, "correction": "plane"}) for n in (8, 16)]
    panels += [Panel("hierarchical", "hierarchical (paper's ground truth)", MILK_BUNNY, "hierarchical"),
               Panel("exact", "exact sum", MILK_BUNNY, "exact"),
               Panel("volpathmis", "volpathmis (path traced)", MILK_BUNNY, "volpathmis")]
    return Figure("fig5", "Fig. 5 — number of layers against the hierarchical method",
                  "Wholemilk bunny at 800×800: 2, 4, 8, 16 layers and the ground truth rendered with the "
                  "hierarchical algorithm [JB02], with times; no optimizations.", tuple(panels), columns=5,
                  versus_pt=True,
                  notes="Threshold 0 and full-resolution layers (no optimizations), as in the paper. Beyond the "
                        "paper: 8 and 16 layers with the plane correction of the depth discretization "
                        "(convsss.transport.correction), the exact sum over the same irradiance samples and a "
                        "volumetric path-traced column.")


FIG6 = (("apple", "bunny", 40.0, 0.0), ("marble", "dragon", 50.0, 0.0), ("skin1", "bust", 60.0, 180.0))


def fig6():
    panels = []
    for material, mesh, size, turn in FIG6:
        spec = SceneSpec(mesh, material, size, "null", turn)
        for method, title in (("convolution", "convolution"), ("hierarchical", "hierarchical"), ("exact", "exact"),
                              ("volpathmis", "volpathmis")):
            panels.append(Panel(f"{material}-{method}", f"{material}: {title}", spec, method, group=material))
        panels.insert(len(panels) - 3, Panel(f"{material}-plane", f"{material}: convolution + plane correction",
                                             spec, params={"correction": "plane"}, group=material))
    return Figure("fig6", "Fig. 6 — convolution beside the hierarchical method",
                  "Left: our algorithm; right: Jensen and Buhler [JB02]; apple, marble [JMLH01], orange juice "
                  "[MES*11].", tuple(panels), columns=5, versus_pt=True,
                  notes="Orange juice of [MES*11] is not in our tables: skin1 [JMLH01] takes its place. "
                        "Index-matched boundary so that volpathmis sees the same scene; 8 layers, t = 0.1 %. "
                        "Beyond the paper: the convolution with the plane correction of its depth discretization.")


#: Figure builders in the paper's order.
FIGURES = {"fig2": fig2, "fig3": fig3, "fig4": fig4, "fig5": fig5, "fig6": fig6}
