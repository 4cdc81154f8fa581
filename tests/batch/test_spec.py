"""A batch's SPEC (convsss.batch.spec): the jobs it makes, and every problem reported before anything runs."""

import pytest

from convsss.batch.spec import SpecError, arguments, batch_from_spec, keywords, read_spec
from convsss.cli.batch import command_parsers
from convsss.scene.source import SceneSource

PARSERS = command_parsers()

BASE = {"mesh": "bunny", "size_mm": 20, "width": 32, "height": 32, "spp": 1}


def test_the_product_of_the_axes_is_the_jobs_with_stable_ids():
    spec = {"scene": BASE, "axes": {"material": ["wholemilk", "marble"], "seed": [1, 2, 3]}}
    batch = batch_from_spec(spec, PARSERS)
    assert batch.command == "render" and len(batch.jobs) == 6 and batch.axes == ("material", "seed")
    assert [j.varied for j in batch.jobs[:2]] == [{"material": "wholemilk", "seed": 1},
                                                  {"material": "wholemilk", "seed": 2}]
    assert batch.jobs[5].id == "0005-material=marble-seed=3"
    again = batch_from_spec(spec, PARSERS)
    assert [j.id for j in again.jobs] == [j.id for j in batch.jobs]  # the same SPEC, the same ids
    assert batch.jobs[0].options == {**BASE, "material": "wholemilk", "seed": 1}
    args = arguments(PARSERS["render"], batch.jobs[0].options)
    assert args[:2] == ["--mesh", "bunny"] and args[-4:] == ["--material", "wholemilk", "--seed", "1"]


def test_a_jobs_options_are_the_library_functions_keywords_converted_as_the_command_converts_them():
    job = batch_from_spec({"scene": {**BASE, "floor": True, "write_mask": True, "spp": "3", "accuracy": "0.02"},
                           "axes": {"material": ["marble"]}}, PARSERS).jobs[0]
    call = keywords(PARSERS["render"], job.options)
    assert call["source"] == SceneSource(mesh="bunny", material="marble", size_mm=20.0, floor=True, width=32,
                                         height=32)
    assert call["spp"] == 3 and call["mask"] is True and call["accuracy"] == 0.02 and call["seed"] == 0
    assert "output" not in call and "progress" not in call and "stats_path" not in call
    listed = batch_from_spec({"command": "reference", "scene": {**BASE, "material": "marble", "pass_spp": 2}}, PARSERS)
    assert keywords(PARSERS["reference"], listed.jobs[0].options)["pass_spp"] == 2


def test_a_table_value_sets_several_options_and_flags_and_listed_jobs():
    spec = {"scene": {**BASE, "floor": True},
            "axes": {"look": [{"color": "0.8,0.5,0.4", "mfp-mm": 2}, {"material": "skin1"}]}}
    jobs = batch_from_spec(spec, PARSERS).jobs
    assert jobs[0].options["mfp_mm"] == 2 and jobs[1].options["material"] == "skin1"
    assert "--floor" in arguments(PARSERS["render"], jobs[0].options)
    listed = batch_from_spec({"command": "reference", "scene": BASE,
                              "jobs": [{"material": "marble", "orbit_deg": 90}, {"material": "ketchup"}]}, PARSERS)
    assert listed.command == "reference" and [j.options["material"] for j in listed.jobs] == ["marble", "ketchup"]


def test_every_problem_is_reported_at_once_one_line_each(tmp_path):
    spec = {"scene": {**BASE, "colour": "red"}, "extra": 1,
            "axes": {"material": ["wholemilk"], "spp": [], "seed": [1]}}
    with pytest.raises(SpecError) as error:
        batch_from_spec(spec, PARSERS)
    problems = error.value.problems
    assert any("unknown key 'extra'" in p for p in problems)
    assert any("unknown option 'colour'" in p for p in problems)
    assert any("axis 'spp' has no values" in p for p in problems)
    assert all("\n" not in p for p in problems)


def test_bad_values_missing_files_and_scenes_that_do_not_load_are_refused_per_job(tmp_path):
    broken = tmp_path / "broken.xml"
    broken.write_text("<scene version='3.0.0'><shape type='nonsense'/></scene>")
    spec = {"scene": {"file": "broken.xml"}, "axes": {"spp": [1, "many"]}}
    with pytest.raises(SpecError) as error:
        batch_from_spec(spec, PARSERS, tmp_path)
    problems = error.value.problems
    assert any(p.startswith("job 0001-spp=many") and "many" in p for p in problems)
    assert sum("does not load" in p for p in problems) == 2
    with pytest.raises(SpecError, match="material 'unobtainium'|unobtainium"):
        batch_from_spec({"scene": BASE, "axes": {"material": ["unobtainium"]}}, PARSERS)
    with pytest.raises(SpecError, match="does not exist"):
        batch_from_spec({"scene": {"file": "absent.xml"}}, PARSERS, tmp_path)
    with pytest.raises(SpecError, match="nothing to render"):
        batch_from_spec({"scene": {"mesh": "bunny", "size_mm": 20}, "axes": {"seed": [1]}}, PARSERS)


def test_too_many_jobs_and_bad_files_are_refused(tmp_path):
    with pytest.raises(SpecError, match="makes 9 jobs, more than --max-jobs 8"):
        batch_from_spec({"scene": BASE, "axes": {"seed": [1, 2, 3], "spp": [1, 2, 3]}}, PARSERS, max_jobs=8)
    bad = tmp_path / "bad.toml"
    bad.write_text("[scene\n")
    with pytest.raises(Exception, match="not valid TOML"):
        read_spec(bad, PARSERS)
    with pytest.raises(Exception, match="does not exist"):
        read_spec(tmp_path / "none.toml", PARSERS)
    with pytest.raises(SpecError, match="command 'fit'"):
        batch_from_spec({"command": "fit", "scene": BASE}, PARSERS)
