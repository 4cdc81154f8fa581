"""The figures' definitions, --only parsing, captions and the shared tone mapping (no rendering)."""

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.figures import FIGURES, FULL, QUICK
from convsss.figures.report import caption
from convsss.figures.run import select
from convsss.figures.scenes import MESHES, mesh_path
from convsss.figures.sheet import tonemap_groups
from convsss.image import Reinhard, srgb_encode, tonemap
from convsss.materials import material


@pytest.mark.filterwarnings("ignore::convsss.materials.OpticallyThinWarning")
def test_every_figure_is_well_formed():
    assert list(FIGURES) == ["fig2", "fig3", "fig4", "fig5", "fig6"]
    for name, build in FIGURES.items():
        figure = build()
        keys = [p.key for p in figure.panels]
        assert len(keys) == len(set(keys)), name
        for panel in figure.panels:
            material(panel.scene.material)  # a known preset
            assert panel.scene.mesh in MESHES
            if panel.method == "volpathmis":
                assert figure.versus_pt and panel.scene.boundary == "null"
    fig2 = FIGURES["fig2"]()
    sizes = sorted({p.scene.size_mm for p in fig2.panels})
    assert sizes[1] == 10 * sizes[0]
    assert sorted({p.params["threshold"] for p in fig2.panels}) == [0.0, 0.001, 0.05]
    fig5 = FIGURES["fig5"]()
    paper = [p for p in fig5.panels if p.method == "convolution" and p.params.get("correction", "none") == "none"]
    assert [p.params["layers"] for p in paper] == [2, 4, 8, 16]
    beyond = [p.params["layers"] for p in fig5.panels if p.params.get("correction") == "plane"]
    assert beyond == [8, 16]
    assert {p.method for p in fig5.panels} == {"convolution", "hierarchical", "exact", "volpathmis"}
    assert len(FIGURES["fig4"]().scenes()) == 10


def test_bundled_meshes_exist():
    for name in MESHES:
        assert mesh_path(name).is_file()


def test_quick_is_smaller_than_full():
    assert QUICK.resolution < FULL.resolution == 800
    assert not QUICK.separate_error_renders and FULL.separate_error_renders


def test_select_parses_only():
    assert select(None) == list(FIGURES)
    assert select("5,fig2") == ["fig2", "fig5"]
    with pytest.raises(ConvsssError, match="unknown figure"):
        select("fig9")
    with pytest.raises(ConvsssError, match="names no figure"):
        select(" , ")


def test_caption_shows_parameters_c_seconds_and_errors():
    record = {"title": "40 mm bunny", "parameters": "8 layers · t = 0.1 % · r = 1", "method": "convolution",
              "c": 2.75, "seconds": 0.5, "sss_seconds": 0.2, "vs_exact": {"mre": 0.031, "ratio": 0.98},
              "vs_pt": {"mre": 0.12, "ratio": 0.9}}
    text = caption(record)
    for part in ("40 mm bunny", "c = 2.8", "0.50 s", "subsurface 0.20 s", "err 3.1 %", "ratio 0.980",
                 "vs volpathmis: err 12.0 %"):
        assert part in text


def test_group_tonemap_keeps_darker_panels_darker():
    rng = np.random.default_rng(1)
    reference = rng.random((8, 8, 3)) + 0.1
    darker = 0.5 * reference
    shown = tonemap_groups([darker, reference], ["g", "g"], {"g": reference})
    assert shown[0].mean() < shown[1].mean()
    assert np.array_equal(shown[1], srgb_encode(Reinhard(reference)(reference)))
    assert np.array_equal(shown[1], srgb_encode(tonemap(reference)))  # one operator: the figures' and the PNGs'
    alone = tonemap_groups([darker, reference], ["a", "b"])  # each on its own: about the same brightness
    assert abs(int(alone[0].mean()) - int(alone[1].mean())) <= 2
