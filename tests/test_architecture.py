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


def _package_imports():
    """``(files, imports)``: the package's modules ``{name: path}`` (a package named for its ``__init__``) and every
    import statement in them, at their top level and inside their functions alike, as ``(module, line, target,
    names)``: ``from .x import y`` is ``("...", n, "convsss....x", ["y"])``, ``import a.b`` is ``(..., "a.b", [])``."""
    import ast

    root = Path(__file__).parents[1] / "src"
    files = {".".join(p.relative_to(root).with_suffix("").parts).removesuffix(".__init__"): p
             for p in (root / "convsss").rglob("*.py")}
    imports = []
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                imports.append((name, node.lineno, target, [a.name for a in node.names]))
            elif isinstance(node, ast.Import):
                imports += [(name, node.lineno, a.name, []) for a in node.names]
    return files, imports


def _module_imports():
    """``{module: modules it imports}`` over the package (:func:`_package_imports`: an import in a function is a
    cycle all the same, met later): ``from .x import y`` is an edge to ``x`` (or to ``x.y`` where that is a module)."""
    files, imports = _package_imports()
    edges = {name: set() for name in files}
    for name, _, target, names in imports:
        subs = {f"{target}.{n}" for n in names} & files.keys()
        edges[name] |= subs | ({target} & files.keys() if len(subs) < max(len(names), 1) else set())
    for name in edges:
        edges[name].discard(name)
    return edges


def test_every_import_of_the_package_names_a_module_that_exists():
    """Imports inside functions too (they fail only when the function runs): scene/source.py imported a module
    moved to media/ inside a method, which only the colour-and-mean-free-path command met."""
    files, imports = _package_imports()
    missing = [f"{name}:{line} {target}" for name, line, target, _ in imports
               if target.startswith("convsss") and target not in files]
    assert not missing, missing


def test_no_module_imports_itself_back_through_others():
    """No import cycle, imports inside functions counted, a package's ``__init__`` counted as the package (one that
    imports a child which imports the package back is a cycle: the package's ``register`` imported the integrator,
    whose session imported ``STAGES`` from the package, issue 59)."""
    edges = _module_imports()
    assert len(edges) > 50 and edges["convsss.pipeline.session"] >= {"convsss.pipeline.stages", "convsss.pipeline.plan"}
    state = {}

    def visit(module, path):
        state[module] = "open"
        for target in edges.get(module, ()):
            assert state.get(target) != "open", " -> ".join(path + [target])
            if target not in state:
                visit(target, path + [target])
        state[module] = "done"

    for module in sorted(edges):
        if module not in state:
            visit(module, [module])


def _where_to_change():
    """The "where to change what" section's pairs "`name` in `pkg/module.py`"."""
    text = PAGE.read_text()
    section = text[text.index("## Where to change what"):text.index("## Physics conventions")]
    return re.findall(r"`([A-Za-z_][A-Za-z_0-9.]*)` in\s+`((?:[a-z_]+/)*[a-z_]+\.py)`", section)


def test_where_to_change_what_names_something():
    assert len(_where_to_change()) >= 10


@pytest.mark.parametrize("name, path", _where_to_change())
def test_where_to_change_what_names_what_its_module_holds(name, path):
    """Issue 59: the page's "where to change what" stays true to the code: each name it places in a module is there."""
    owner = importlib.import_module("convsss." + path[:-3].replace("/", "."))
    for part in name.split("."):
        owner = getattr(owner, part)
