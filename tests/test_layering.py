"""Layering of the package (docs/conventions.md): nothing outside ``drake_est/cli`` imports ``drake_est.cli``,
loaders in ``drake_est/datasets`` import no analysis packages, and there is no import cycle among
``drake_est`` modules.  A static (AST) check of every ``import`` statement, module-level or inside a
function (a function-level import is still a dependency), except those under ``if TYPE_CHECKING:`` and
inside a module-level ``__getattr__`` (a deprecation alias that forwards a moved name; it is not a dependency
of the module's own code).  ``drake_est.__main__`` is the CLI's entry point and may import it."""
import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "drake_est"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


MODULES = {_module_name(p): p for p in PKG.rglob("*.py") if ".venv" not in p.parts}


def _resolve(name: str) -> str | None:
    """The drake_est module a dotted name refers to (longest existing prefix), or None."""
    parts = name.split(".")
    while parts:
        cand = ".".join(parts)
        if cand in MODULES:
            return cand
        parts = parts[:-1]
    return None


def _is_type_checking(node) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imports(mod: str) -> set:
    path = MODULES[mod]
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    out = set()

    def visit(node):
        for child in ast.iter_child_nodes(node):
            if _is_type_checking(child):
                continue
            if node is tree and isinstance(child, ast.FunctionDef) and child.name == "__getattr__":
                continue
            if isinstance(child, ast.Import):
                for a in child.names:
                    if a.name.startswith("drake_est"):
                        out.add(_resolve(a.name))
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    base = base[: len(base) - (child.level - 1)]
                    src = ".".join(base + ([child.module] if child.module else []))
                else:
                    src = child.module or ""
                if not src.startswith("drake_est"):
                    continue
                for a in child.names:   # "from pkg import submodule" depends on the submodule
                    target = _resolve(f"{src}.{a.name}")
                    out.add(target if target == f"{src}.{a.name}" else _resolve(src))
            visit(child)

    visit(tree)
    out.discard(None)
    out.discard(mod)
    return out


GRAPH = {m: _imports(m) for m in MODULES}
ENTRY_POINTS = {"drake_est.__main__"}


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    import sys
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))
    for v in sorted(graph):
        if v not in index:
            strong(v)
    return comps


def test_the_scan_sees_known_imports():
    # guards the checker itself: a module known to import another must show the edge
    assert "drake_est.errors" in GRAPH["drake_est.data"]
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]


def test_nothing_outside_cli_imports_cli():
    bad = sorted(f"{m} imports {t}" for m, ts in GRAPH.items() if not m.startswith("drake_est.cli")
                 and m not in ENTRY_POINTS for t in ts if t == "drake_est.cli" or t.startswith("drake_est.cli."))
    assert not bad, "library/reproductions import the CLI: " + "; ".join(bad)


def test_reproductions_and_cases_stay_above_the_library():
    order = {"drake_est.cli": 3, "drake_est.reproduce": 2, "drake_est.cases": 1}

    def layer(m):
        return next((v for k, v in order.items() if m == k or m.startswith(k + ".")), 0)
    bad = sorted(f"{m} imports {t}" for m, ts in GRAPH.items() if m not in ENTRY_POINTS
                 for t in ts if layer(t) > layer(m))
    assert not bad, "imports pointing upwards (cli > reproduce > cases > library): " + "; ".join(bad)


def test_loaders_only_load():
    analysis = ("drake_est.identification", "drake_est.spectral", "drake_est.diagnose", "drake_est.calibration",
                "drake_est.estimation", "drake_est.control", "drake_est.cases", "drake_est.reproduce")
    bad = sorted(f"{m} imports {t}" for m, ts in GRAPH.items() if m.startswith("drake_est.datasets")
                 for t in ts if t.startswith(analysis))
    assert not bad, "dataset loaders import analysis code (move it to drake_est/cases): " + "; ".join(bad)


def test_no_import_cycles():
    cycles = _cycles(GRAPH)
    msg = []
    for comp in cycles:
        edges = [f"{a} -> {b}" for a in comp for b in sorted(GRAPH[a]) if b in comp]
        msg.append("{" + ", ".join(comp) + "}: " + "; ".join(edges))
    assert not cycles, "import cycles: " + " | ".join(msg)
