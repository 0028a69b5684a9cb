"""The layers of docs/architecture.md, read from the import statements of the source
(module level and inside functions alike)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("engine", "drivers", "mock_hw", "labid")
#: front-ends reach run files and workflows through labid.services only
FRONT_ENDS = ("labid.gui", "labid.report", "labid.cli")
#: the physics commands touch no run file and call engine directly (start-up time); identify and
#: diagnose still build their problems themselves (issue 23 merges them into services)
NOT_YET = ("labid.cli.dispersion", "labid.cli.modes", "labid.cli.identify", "labid.cli.diagnose",
           "labid.cli.main", "labid.cli.options")


def modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for f in (ROOT / pkg).rglob("*.py"):
            name = ".".join(f.relative_to(ROOT).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = f
    return out


def import_graph() -> dict[str, set[str]]:
    """module -> the project modules it imports."""
    mods = modules()
    graph: dict[str, set[str]] = {}
    for m, f in mods.items():
        pkg = m.split(".") if f.name == "__init__.py" else m.split(".")[:-1]
        deps: set[str] = set()
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                deps.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = pkg[:len(pkg) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                for a in node.names:
                    full = f"{target}.{a.name}"
                    deps.add(full if full in mods else target)
        graph[m] = {d for d in deps if d in mods and d != m}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_the_checker_sees_imports_and_cycles():
    g = import_graph()
    assert "labid.store.runstore" in g["labid.store"] and "labid.base.errors" in g["labid.store.runstore"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["c", "b", "a"]]


def test_labid_has_no_import_cycle():
    g = import_graph()
    assert cycles({m: {d for d in ds if d.startswith("labid")} for m, ds in g.items()
                   if m.startswith("labid")}) == []


def test_engine_and_drivers_import_nothing_above_them():
    for m, ds in import_graph().items():
        if m.startswith("engine"):
            assert all(d.startswith("engine") for d in ds), (m, ds)
        if m.startswith("drivers"):
            assert all(d.startswith("drivers") for d in ds), (m, ds)


def test_front_ends_reach_run_files_and_engine_through_services():
    for m, ds in import_graph().items():
        if m.startswith(FRONT_ENDS) and m not in NOT_YET:
            bad = [d for d in ds if d.startswith(("labid.store", "engine", "mock_hw", "drivers"))]
            assert not bad, f"{m} imports {bad}; expected labid.services"


def test_no_import_cycle_anywhere():
    assert cycles(import_graph()) == []


def test_mock_hw_imports_engine_and_drivers_only():
    for m, ds in import_graph().items():
        if m.startswith("mock_hw"):
            assert all(d.startswith(("engine", "drivers", "mock_hw")) for d in ds), (m, ds)


def test_no_private_name_is_imported_from_another_module():
    bad = []
    for m, f in modules().items():
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom):
                bad += [(m, node.module, a.name) for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
    assert bad == []


def test_long_modules_say_why_at_their_top():
    """A module over 500 lines says why in its first 15 lines ('... 500 lines ...')."""
    long = []
    for m, f in modules().items():
        lines = f.read_text().splitlines()
        if len(lines) > 500 and "500 lines" not in "\n".join(lines[:15]):
            long.append((m, len(lines)))
    assert long == []
