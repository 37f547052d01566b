"""The module import graph of the envcap package, read from the source with ``ast`` (nothing is
imported).  Used by ``tests/test_architecture.py`` and ``docs/images/make_architecture_figure.py``
(not a test module)."""

from __future__ import annotations

import ast
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# The pipeline order of the packages: an arrow from a later package to an earlier one is a
# normal dependency; the figure draws them in this order.
PIPELINE = ("core", "gpu", "outputs", "sky", "scene", "capture", "prefilter", "formats", "probeset",
            "runtime", "city", "dynamic", "evaluate", "crowd", "placement", "viewer", "export", "benchmarks", "cli")


@dataclass
class ImportGraph:
    """``modules``: dotted name -> source path; ``edges``: module -> modules it imports (anywhere
    in the file, function-level imports included); ``private``: (importer, module, name) for each
    ``_name`` imported from another module; ``inner``: (module, line) of each envcap import made
    inside a function."""

    modules: dict[str, Path]
    edges: dict[str, set[str]]  # imports under ``if TYPE_CHECKING:`` are not run, so not edges
    private: list[tuple[str, str, str]] = field(default_factory=list)
    inner: list[tuple[str, int]] = field(default_factory=list)

    def package_of(self, module: str) -> str:
        parts = module.split(".")
        return parts[1] if len(parts) > 1 else "envcap"

    def package_edges(self) -> set[tuple[str, str]]:
        out = set()
        for a, targets in self.edges.items():
            for b in targets:
                pa, pb = self.package_of(a), self.package_of(b)
                if pa != pb:
                    out.add((pa, pb))
        return out

    def cycles(self) -> list[list[str]]:
        """Strongly connected components of more than one module (Tarjan)."""
        index: dict[str, int] = {}
        low: dict[str, int] = {}
        stack: list[str] = []
        on: set[str] = set()
        found: list[list[str]] = []
        counter = [0]

        def visit(v: str) -> None:
            index[v] = low[v] = counter[0]
            counter[0] += 1
            stack.append(v)
            on.add(v)
            for w in sorted(self.edges[v]):
                if w not in index:
                    visit(w)
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
                    found.append(sorted(comp))

        for v in sorted(self.edges):
            if v not in index:
                visit(v)
        return found


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph(root: Path = REPO) -> ImportGraph:
    """Parse every ``envcap/**/*.py`` under ``root``.  An import of a package's ``__init__`` counts
    as an edge to the package module; ``from envcap.a import b`` is an edge to ``envcap.a.b`` when
    that is a module, else to ``envcap.a``."""
    modules = {_module_name(p, root): p for p in sorted((root / "envcap").rglob("*.py"))}

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rsplit(".", 1)[0] if "." in name else ""
        return name or None

    graph = ImportGraph(modules, {m: set() for m in modules})
    for mod, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        function_nodes = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                          for n in ast.walk(f)}
        type_only = {id(n) for f in ast.walk(tree) if isinstance(f, ast.If) and "TYPE_CHECKING" in ast.unparse(f.test)
                     for n in ast.walk(f)}
        for node in ast.walk(tree):
            targets: list[str | None] = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and node.module.startswith("envcap"):
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    target = full if full in modules else resolve(node.module)
                    targets.append(target)
                    if alias.name.startswith("_") and not alias.name.startswith("__") and target != mod:
                        graph.private.append((mod, node.module, alias.name))
            elif isinstance(node, ast.Import):
                targets = [resolve(a.name) for a in node.names if a.name.startswith("envcap")]
            else:
                continue
            if id(node) in type_only:
                continue
            if targets and id(node) in function_nodes:
                graph.inner.append((mod, node.lineno))
            graph.edges[mod].update(t for t in targets if t and t != mod)
    return graph
