"""The layers of docs/architecture.md, read from the import statements of the source
(module level and inside functions alike)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("engine", "drivers", "mock_hw", "labid")
#: the layers of labid, top down; a package imports only from its own layer or those below
#: (engine, drivers and mock_hw beneath them all)
FRONT_ENDS = ("labid.gui", "labid.report", "labid.cli")
#: the facade: labid.services and the modules it is written in (re-exported by it)
FACADE = ("labid.services", "labid.inference", "labid.runresults", "labid.picks", "labid.display")
WORKFLOWS = ("labid.workflows",)
FILES = ("labid.io", "labid.store")
INPUTS = ("labid.inputs", "labid.base")
#: the physics commands touch no run file and call engine directly: importing the services'
#: workflows would triple their start-up time
PHYSICS_COMMANDS = ("labid.cli.dispersion", "labid.cli.modes")


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


def test_front_ends_reach_workflows_files_and_engine_through_services():
    """The CLI, the panel and the report import labid.services (not the modules it is
    written in), labid.inputs and labid.base, and each other; never a workflow, the run
    store, the io package, engine, mock_hw or drivers (the physics commands: engine only)."""
    below = ("labid.store", "labid.io", "labid.workflows", "engine", "mock_hw", "drivers") + FACADE[1:]
    for m, ds in import_graph().items():
        if m.startswith(FRONT_ENDS):
            allowed = ("engine",) if m in PHYSICS_COMMANDS else ()
            bad = [d for d in ds if d.startswith(below) and not d.startswith(allowed)]
            assert not bad, f"{m} imports {bad}; expected labid.services"


def test_each_layer_imports_only_its_own_and_those_below():
    """workflows import no facade or front-end; io and store no workflow; inputs and base
    no workflow, no file package (io, store) and nothing above."""
    above = {WORKFLOWS: FACADE + FRONT_ENDS, FILES: WORKFLOWS + FACADE + FRONT_ENDS,
             INPUTS: FILES + WORKFLOWS + FACADE + FRONT_ENDS}
    bad = []
    for m, ds in import_graph().items():
        for layer, forbidden in above.items():
            if m.startswith(layer):
                bad += [(m, d) for d in ds if d.startswith(forbidden)]
    assert bad == []


def test_no_package_loop_in_labid():
    """No cycle between labid's packages (a module of io importing a workflow that imports
    io again was one): the graph of package -> package has no cycle."""
    pkg = {}
    for m, ds in import_graph().items():
        if m.startswith("labid."):
            a = ".".join(m.split(".")[:2])
            pkg.setdefault(a, set()).update(".".join(d.split(".")[:2]) for d in ds
                                            if d.startswith("labid.") and ".".join(d.split(".")[:2]) != a)
    for a in list(pkg):
        for d in pkg[a]:
            pkg.setdefault(d, set())
    assert cycles(pkg) == []


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


def test_no_module_is_over_500_lines():
    """One concept, one module, readable alone: none of engine, drivers, mock_hw, labid is
    over 500 lines (split it; a facade may re-export)."""
    long = [(m, n) for m, f in modules().items() if (n := len(f.read_text().splitlines())) > 500]
    assert long == []
