"""The architecture page (docs/architecture.md) is true to the code: every module its data flow names exists and
holds the function or class named beside it, and the stages it numbers are the session's."""

import importlib
import re
from pathlib import Path

import pytest

PAGE = Path(__file__).parents[1] / "docs" / "architecture.md"


def _flow():
    """The data-flow block's (module path, name) pairs: ``pkg/module.py  name`` on a line."""
    text = PAGE.read_text()
    block = text[text.index("## The data flow"):text.index("| stage |")]
    return re.findall(r"\b([a-z_]+(?:/[a-z_]+)*\.py)\s+([A-Za-z_][A-Za-z_0-9.]*)\s*$", block, flags=re.M)


def test_the_data_flow_names_something():
    assert len(_flow()) >= 12


@pytest.mark.parametrize("path, name", _flow())
def test_each_stage_names_a_module_and_a_name_that_exist(path, name):
    module = importlib.import_module("convsss." + path[:-3].replace("/", "."))
    owner = module
    for part in name.split("."):
        owner = getattr(owner, part)


def test_every_module_the_page_cites_exists():
    repository = Path(__file__).parents[1]
    cited = set(re.findall(r"`((?:[a-z_]+/)+[a-z_]+\.py)`", PAGE.read_text()))
    where = {p: repository / p if p.startswith(("tests/", "docs/")) else repository / "src" / "convsss" / p
             for p in cited}
    missing = [p for p in sorted(cited) if not where[p].is_file()]
    assert not missing, missing


def test_the_stages_are_numbered_as_the_session_runs_them():
    from convsss.pipeline import STAGES

    text = PAGE.read_text()
    block = text[text.index("## The data flow"):text.index("| stage |")]
    numbered = re.findall(r"^ (\d) ([a-z]+)", block, flags=re.M)
    assert [name for _, name in numbered] == list(STAGES)
    assert [int(k) for k, _ in numbered] == list(range(1, len(STAGES) + 1))
