"""The layering of docs/architecture.md, enforced on the source (AST, no import side effects).

Every ``import`` and ``from ... import`` anywhere in a module counts, including the ones
inside functions (a lazy import is still a dependency), and so does a string constant
naming a dotted project module (``"app.viewer"``, ``"app.exports._qgc:export_qgc_plan"``), the
way plugin registries refer to code. From that graph:

* no cycle between modules (a strongly connected component of size > 1);
* every package imports only packages on lower layers of :data:`LAYERS`, so no
  package cycle either (and sim never imports app, formations never imports sim).

import-linter could express the layers but not "no module cycle anywhere", and it
ignores the registry strings; 100 lines of ``ast`` do both.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOP_PACKAGES = ("app", "sim", "formations")

#: Components from the top of the data flow's consumers down to the show file. A component
#: may import only components on *lower* lines; components on one line are independent.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("app.cli",),
    ("app.server",),
    ("app.viewer",),
    ("app.api",),
    ("app.jobs",),
    ("app.tasks",),
    ("app.exports", "app.store"),
    ("app.settings", "app.version", "app.web", "app.media"),
    ("sim.bench", "sim.flight", "sim"),
    ("sim.light",),
    ("sim.verify",),
    ("sim.plan",),
    ("sim.geometry",),
    ("formations",),
)


def component_of(module: str) -> str | None:
    """The longest layer component that is ``module`` or contains it (``app`` itself has none)."""
    best = None
    for line in LAYERS:
        for comp in line:
            if (module == comp or module.startswith(comp + ".")) and (best is None or len(comp) > len(best)):
                best = comp
    return best


def _modules(root: Path) -> dict[str, tuple[Path, bool]]:
    out = {}
    for top in TOP_PACKAGES:
        for path in sorted((root / top).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            if is_pkg:
                parts = parts[:-1]
            out[".".join(parts)] = (path, is_pkg)
    return out


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the project modules it names (imports anywhere, registry strings)."""
    mods = _modules(root)

    def resolve(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for name, (path, is_pkg) in mods.items():
        package = name if is_pkg else name.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join([*parts, base] if base else parts)
                # ``from pkg import mod`` names the submodule when there is one.
                targets.update(f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                text = node.value.partition(":")[0]
                # Dotted names only: a bare "formations" is the show file's JSON key, not code.
                if "." in text and text.startswith(TOP_PACKAGES) and text in mods:
                    targets.add(text)
        graph[name] = {m for t in targets if (m := resolve(t)) is not None and m != name}
    return graph


def module_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph) + 100))
    try:
        for v in sorted(graph):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return out


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """``"a -> b"`` for every import from a component to one on the same or a higher layer."""
    rank = {comp: i for i, line in enumerate(LAYERS) for comp in line}
    bad = []
    for src, targets in sorted(graph.items()):
        a = component_of(src)
        for dst in sorted(targets):
            b = component_of(dst)
            if a is None or b is None or a == b:
                continue
            if rank[b] <= rank[a]:
                bad.append(f"{src} ({a}) -> {dst} ({b})")
    return bad


def test_every_module_is_in_a_layer() -> None:
    graph = import_graph(ROOT)
    assert len(graph) > 80  # the walk found the code base
    loose = [m for m in graph if component_of(m) is None and m != "app"]
    assert loose == [], f"add these modules' package to LAYERS (and docs/architecture.md): {loose}"


def test_no_module_cycles() -> None:
    assert module_cycles(import_graph(ROOT)) == []


def test_packages_import_only_lower_layers() -> None:
    assert layer_violations(import_graph(ROOT)) == []


def test_sim_and_formations_stay_below_the_app() -> None:
    graph = import_graph(ROOT)
    for src, targets in graph.items():
        if src.startswith("sim"):
            assert not any(t.startswith("app") for t in targets), src
        if src.startswith("formations"):
            assert not any(t.startswith(("app", "sim")) for t in targets), src


def _write(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def test_the_checks_catch_a_cycle_a_lazy_import_and_a_registry_string(tmp_path: Path) -> None:
    """The checker itself: a planted cycle, an upward lazy import and a registry string are all found."""
    _write(tmp_path, {
        "app/__init__.py": "",
        "app/exports/__init__.py": "from app.exports._core import run as run\n",
        "app/exports/_core.py": 'FORMATS = {"html": "app.viewer:html"}\n',
        "app/viewer/__init__.py": "def html():\n    from app.exports import run\n    return run\n",
        "sim/__init__.py": "",
        "sim/plan/__init__.py": "from . import _a\n",
        "sim/plan/_a.py": "from sim.plan._b import x\n",
        "sim/plan/_b.py": "x = 1\n\ndef f():\n    from sim.plan import _a\n    import app.exports\n",
        "formations/__init__.py": "",
    })
    graph = import_graph(tmp_path)
    assert graph["app.exports._core"] == {"app.viewer"}
    assert graph["sim.plan._b"] == {"sim.plan._a", "app.exports"}
    cycles = module_cycles(graph)
    assert ["sim.plan._a", "sim.plan._b"] in cycles
    assert any("app.viewer" in c and "app.exports._core" in c for c in cycles)
    bad = layer_violations(graph)
    assert "app.exports._core (app.exports) -> app.viewer (app.viewer)" in bad
    assert "sim.plan._b (sim.plan) -> app.exports (app.exports)" in bad


@pytest.mark.parametrize("line", LAYERS)
def test_layers_are_documented(line: tuple[str, ...]) -> None:
    doc = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    for comp in line:
        assert f"`{comp}`" in doc, f"docs/architecture.md does not mention {comp}"
