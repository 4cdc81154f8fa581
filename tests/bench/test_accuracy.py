import json

import numpy as np
import pytest
from click.testing import CliRunner

from convsss.bench.accuracy import bench_points, convolution_configs, error_metrics, hierarchical_configs
from convsss.bench.pareto import headline, headline_text, pareto_front, time_at_error
from convsss.bench.transport import lit_sphere
from convsss.cli import cli
from convsss.materials import material
from convsss.profiles import model_profile
from convsss.samples import ViewFrame

ROW_KEYS = {"scene", "transport", "method", "correction", "label", "layers", "downsample", "threshold", "epsilon",
            "seconds", "seconds_runs", "stage_median_s", "rel_l2", "mean_rel", "max_rel", "points", "samples",
            "pareto"}


@pytest.fixture(scope="module")
def sphere_rows():
    """The numpy core on a lit 10 mm sphere: 6400 samples, 300 front points as the visible points."""
    samples, front = lit_sphere(6400)
    points = front[np.random.default_rng(1).choice(len(front), 300, replace=False)]
    configs = convolution_configs((2, 8), (1.0,), (0.001,)) + hierarchical_configs((0.01, 0.2, 2.0))
    frame = ViewFrame.look_at([0, 0, 100], [0, 0, 0])
    milk = model_profile("dipole", material("wholemilk"))
    return bench_points(samples, points, milk, frame, 20.0 / 64, configs, runs=2, scene="sphere",
                        normals=points / np.linalg.norm(points, axis=1, keepdims=True))


@pytest.mark.slow
def test_rows_have_their_keys_and_the_exact_sum_first(sphere_rows):
    assert [r["transport"] for r in sphere_rows] == ["exact"] + ["convolution"] * 4 + ["hierarchical"] * 3
    assert [r["method"] for r in sphere_rows][1:5] == ["convolution"] * 2 + ["convolution+plane"] * 2
    for row in sphere_rows:
        assert ROW_KEYS <= set(row)
        assert row["points"] == 300 and row["samples"] == 6400
        assert len(row["seconds_runs"]) == (1 if row["transport"] == "exact" else 2)
        assert row["seconds"] > 0 and row["rel_l2"] >= 0
    exact = sphere_rows[0]
    assert exact["rel_l2"] == exact["mean_rel"] == exact["max_rel"] == 0.0 and not exact["pareto"]
    conv = [r for r in sphere_rows if r["transport"] == "convolution"]
    assert all("fft_shape" in r and "kernels" in r["stage_median_s"] for r in conv)
    assert [r["label"] for r in sphere_rows[1:]] == ["L2 d1 t0.001", "L8 d1 t0.001", "L2 d1 t0.001 +plane",
                                                     "L8 d1 t0.001 +plane", "eps0.01", "eps0.2", "eps2"]


def test_errors_behave(sphere_rows):
    hier = [r for r in sphere_rows if r["transport"] == "hierarchical"]
    errors = [r["rel_l2"] for r in sorted(hier, key=lambda r: r["epsilon"])]
    assert errors[0] < 1e-3  # epsilon 0.01 is nearly the exact sum
    assert errors[0] < errors[1] < errors[2]  # and the error grows with epsilon
    two, eight = (r["rel_l2"] for r in sphere_rows if r["method"] == "convolution")
    assert eight < two  # more layers, a finer depth discretization
    _, eight_plane = (r["rel_l2"] for r in sphere_rows if r["method"] == "convolution+plane")
    assert eight_plane < eight / 2  # the plane correction of the depth discretization
    assert any(r["pareto"] for r in hier) and any(r["pareto"] for r in sphere_rows if r["transport"] == "convolution")


def test_error_metrics_of_a_scaled_answer():
    reference = np.random.default_rng(0).random((50, 3)) + 0.5
    m = error_metrics(1.1 * reference, reference)
    assert m["rel_l2"] == pytest.approx(0.1) and m["mean_rel"] == pytest.approx(0.1)
    assert m["max_rel"] == pytest.approx(0.1)


def _rows(method, pairs):
    return [{"transport": method, "seconds": t, "rel_l2": e, "epsilon": k, "label": f"{method[0]}{k}"}
            for k, (t, e) in enumerate(pairs)]


def test_pareto_front_keeps_the_undominated_points_fastest_first():
    rows = _rows("convolution", [(1.0, 0.5), (2.0, 0.6), (3.0, 0.2), (0.5, 0.9), (4.0, 0.2)])
    assert pareto_front(rows) == [3, 0, 2]


def test_time_at_error_interpolates_log_log_and_says_when_outside():
    front = _rows("convolution", [(1.0, 0.4), (4.0, 0.1)])
    seconds, where = time_at_error(front, 0.2)
    assert where == "inside" and seconds == pytest.approx(2.0)  # halfway in log error, halfway in log time
    assert time_at_error(front, 0.05) == (None, "below")
    assert time_at_error(front, 0.8) == (None, "above")
    assert time_at_error(front, 0.4) == (pytest.approx(1.0), "inside")


def test_headline_ratio_with_and_without_overlap():
    conv = _rows("convolution", [(1.0, 0.4), (4.0, 0.1)])
    rows = conv + _rows("hierarchical", [(1.0, 0.2), (8.0, 0.01)])
    h = headline(rows)
    assert h["overlap"] == 1 and h["ratio_median"] == pytest.approx(2.0)  # conv 2 s vs hierarchical 1 s at 20 %
    assert "at equal error = 2.00" in headline_text("s", h)
    apart = headline(conv + _rows("hierarchical", [(0.5, 0.05), (8.0, 0.01)]))
    assert apart["overlap"] == 0 and apart["ratio_median"] is None
    assert all(p["bound"] for p in apart["at_convolution"])  # every conv point: slower and less accurate
    assert "no hierarchical point" in headline_text("s", apart)


@pytest.mark.slow
def test_bench_accuracy_quick_end_to_end(tmp_path, monkeypatch):
    import convsss.bench.accuracy as accuracy

    summed = accuracy.exact_reference  # kept in the test's folder, not the user's cache
    monkeypatch.setattr(accuracy, "exact_reference", lambda s, p, profile, cache: summed(s, p, profile, tmp_path))
    result = CliRunner().invoke(cli, ["bench", "accuracy", "--quick", "--width", "48", "--runs", "1", "--json",
                                      "--output", str(tmp_path)])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert set(out) == {"meta", "rows", "headline"}
    assert set(out["meta"]["scenes"]) == {"bunny4", "bunny40"}
    assert out["meta"]["scenes"]["bunny4"]["size_mm"] == 4 and out["meta"]["scenes"]["bunny40"]["size_mm"] == 40
    for scene in ("bunny4", "bunny40"):
        rows = [r for r in out["rows"] if r["scene"] == scene]
        assert [r["transport"] for r in rows].count("multiscale") == 2
        assert [r["transport"] for r in rows].count("convolution") == 4
        assert [r["method"] for r in rows].count("convolution+plane") == 2
        assert [r["transport"] for r in rows].count("hierarchical") == 3
        assert rows[0]["transport"] == "exact" and rows[0]["points"] > 50
        for name in (scene, f"{scene} multiscale", f"{scene} convolution+plane"):
            assert {"at_hierarchical", "at_convolution", "overlap"} <= set(out["headline"][name])
    assert (tmp_path / "accuracy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((tmp_path / "accuracy.json").read_text())["rows"] == out["rows"]
    assert "front" in (tmp_path / "accuracy.txt").read_text()


@pytest.mark.slow
def test_a_case_takes_the_profile_the_renderer_would():
    from convsss.bench.scenes import prepare_case, scene_dict
    from convsss.profiles import DEFAULT_PROFILE, PROFILE_MODELS, ScaledProfile

    for spec, model in (("", DEFAULT_PROFILE), ("pbd", "pbd"), ("better-dipole", "better-dipole")):
        case = prepare_case(scene_dict("bunny4", 24), sample_density=0.5, profile=spec)
        profile = case["profile"]  # at the exact total, the renderer's default profile_total
        assert isinstance(profile, ScaledProfile) and type(profile.base) is PROFILE_MODELS[model]
        assert case["object"]["profile"].startswith(f"ScaledProfile({PROFILE_MODELS[model].__name__}")


def test_bench_accuracy_refuses_a_bad_profile_in_one_line():
    result = CliRunner().invoke(cli, ["bench", "accuracy", "--quick", "--profile", "pdb"])
    assert result.exit_code != 0 and "profile model 'pdb' is not allowed" in result.output
    assert "Traceback" not in result.output
