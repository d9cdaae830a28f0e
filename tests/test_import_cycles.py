"""No import cycle among avsim's modules, not even one hidden by an import inside a function.

A function-level import that closes a cycle hides it from Python's import machinery but not from a
reader: the two modules still need each other, and the shared piece belongs in a third module. Lazy
imports that close no cycle (the CLI's, to keep `avsim --help` fast) are fine and not flagged.

The same holds one level up, between avsim's top-level packages (and top-level modules): no two
may need each other, and the library packages import nothing from the layers built on them.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parents[1] / "avsim"


def module_name(path: Path) -> str:
    """Dotted module name of a source file under the package, e.g. 'avsim.experiments.batch'."""
    parts = path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(tree: ast.AST, this_module: str, known: set[str]) -> set[str]:
    """The avsim modules a module's source imports anywhere (top level or inside functions)."""
    found = set()
    package = this_module if this_module in known and (PACKAGE_DIR.parent / this_module.replace(".", "/") / "__init__.py").exists() \
        else this_module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            names = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            # `from avsim.x import y` names module avsim.x.y when y is a submodule, else avsim.x.
            if name in known:
                found.add(name)
    found.discard(this_module)
    return found


def import_graph() -> dict[str, set[str]]:
    """Module -> the avsim modules it imports."""
    sources = {module_name(p): p for p in PACKAGE_DIR.rglob("*.py")}
    known = set(sources)
    return {name: imported_modules(ast.parse(path.read_text()), name, known) for name, path in sources.items()}


def strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's strongly connected components with more than one module (each is an import cycle)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for succ in graph.get(node, ()):
            if succ not in index:
                visit(succ)
                low[node] = min(low[node], low[succ])
            elif succ in on_stack:
                low[node] = min(low[node], index[succ])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == node:
                    break
            if len(component) > 1:
                components.append(component)

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return components


def without_package_inits(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph less edges into and out of `__init__` modules that only re-export (importing
    `avsim.x.y` runs `avsim.x/__init__`, which is not a dependency of avsim.x.y's code)."""
    inits = {name for name in graph if (PACKAGE_DIR.parent / name.replace(".", "/") / "__init__.py").exists()}
    return {name: {m for m in deps if m not in inits} for name, deps in graph.items() if name not in inits}


def test_the_package_has_no_import_cycles() -> None:
    cycles = strongly_connected(without_package_inits(import_graph()))
    assert not cycles, "modules that import each other (move the shared piece into a third module): " + "; ".join(
        " <-> ".join(sorted(c)) for c in cycles)


def package_of(module: str) -> str:
    """The top-level piece of avsim a module belongs to: 'avsim.experiments' for
    'avsim.experiments.attacks.success', 'avsim.loop' for the module avsim.loop itself."""
    return ".".join(module.split(".")[:2])


def package_graph() -> dict[str, set[str]]:
    """Top-level package (or module) -> the other top-level pieces its modules import.

    The root package `avsim` (its `__init__` only sets MUJOCO_GL and the version) is left out."""
    graph: dict[str, set[str]] = {}
    for module, deps in import_graph().items():
        if module == "avsim":
            continue
        targets = graph.setdefault(package_of(module), set())
        targets.update(package_of(dep) for dep in deps if dep != "avsim")
    return {package: deps - {package} for package, deps in graph.items()}


def test_no_two_packages_need_each_other() -> None:
    # A cycle between packages hides from the module-level test when no single module closes it:
    # attacks.budget_success imported experiments.batch while experiments.report_sections
    # imported attacks.success. The lower package must not know the upper one.
    cycles = strongly_connected(package_graph())
    assert not cycles, "packages that import each other (move the piece the lower one needs down, or the " \
                       "piece that needs the upper one up): " + "; ".join(" <-> ".join(sorted(c)) for c in cycles)


# The library: what a simulation and an attack are made of. The experiments, the gym environment
# and the command line are built on it, never the other way round.
LIBRARY_PACKAGES = ("avsim.world", "avsim.vehicle", "avsim.sensors", "avsim.perception", "avsim.control",
                    "avsim.attacks")


def is_application(package: str) -> bool:
    """The layers built on the library: experiments, the gym environment and the command line."""
    return package in ("avsim.experiments", "avsim.gym", "avsim.cli", "avsim.__main__")


def test_the_library_imports_no_experiments_gym_or_cli() -> None:
    graph = import_graph()
    upward = sorted(f"{module} -> {dep}" for module, deps in graph.items() if package_of(module) in LIBRARY_PACKAGES
                    for dep in deps if is_application(package_of(dep)))
    assert not upward, "library modules that import experiments, gym or the CLI (move the piece up, into its " \
                       "user): " + "; ".join(upward)
