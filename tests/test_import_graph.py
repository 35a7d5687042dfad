"""The package's import graph, read from the sources (every import, at module level or
inside a function): no two modules import each other, no cycle, and no layer imports
one above it (models < sensors < estimators < scenarios < the aligngym root)."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("models", "sensors", "estimators", "scenarios")


def modules() -> dict[str, Path]:
    """aligngym module name -> source file."""
    out = {}
    for sub in ("aligngym", *LAYERS):
        for path in (ROOT / sub).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts if sub == "aligngym" else ["aligngym", *parts])] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the package modules it imports (``from P import m`` with m a module is an
    import of P.m only)."""
    mods = modules()
    graph = {m: set() for m in mods}
    for name, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                subs = [f"{node.module}.{a.name}" for a in node.names
                        if f"{node.module}.{a.name}" in mods]
                graph[name].update(subs)
                if len(subs) < len(node.names) and node.module in mods:
                    graph[name].add(node.module)
            elif isinstance(node, ast.Import):
                graph[name].update(a.name for a in node.names if a.name in mods)
        graph[name].discard(name)
    return graph


def layer(module: str) -> int:
    """0 models ... 3 scenarios, 4 the aligngym root (API, testing, pytest plugin)."""
    part = module.split(".")[1] if "." in module else ""
    return LAYERS.index(part) if part in LAYERS else len(LAYERS)


def test_the_graph_is_read():
    graph = import_graph()
    assert "aligngym.estimators.catalogue" in graph["aligngym.scenarios.campaign.runs"]
    assert len(graph) > 50


def test_no_two_modules_import_each_other_and_no_cycle():
    graph = import_graph()
    mutual = sorted({tuple(sorted((a, b))) for a in graph for b in graph[a]
                     if a in graph.get(b, ())})
    assert mutual == []
    # Tarjan's strongly connected components: every one a single module.
    index, low, stack, on, cycles, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert cycles == []


def test_no_layer_imports_one_above_it():
    graph = import_graph()
    upward = sorted((a, b) for a in graph for b in graph[a]
                    if layer(b) > layer(a) and b != "aligngym")
    assert upward == []
