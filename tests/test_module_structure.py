"""No module of the package imports one that imports it back (directly or through others), counting imports made
inside functions too: a cycle means two modules that cannot be understood, tested or moved apart."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "sb3_maddpg"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_imports() -> dict[str, set[str]]:
    """:return: Each module of the package and the package modules it imports anywhere in its code."""
    modules = {module_name(path): path for path in PACKAGE.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                # `from a.b import c`: the module a.b.c if there is one, else a.b.
                targets |= {
                    f"{node.module}.{alias.name}" if f"{node.module}.{alias.name}" in modules else node.module
                    for alias in node.names
                }
        graph[name] = {target for target in targets if target in modules and target != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """:return: The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for target in sorted(graph[node]):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_the_package_has_no_import_cycle() -> None:
    graph = package_imports()
    assert {"sb3_maddpg.maddpg", "sb3_maddpg.sharing.base", "sb3_maddpg.cli.main"} <= set(graph)
    assert "sb3_maddpg.sharing.base" in graph["sb3_maddpg.sharing.learned"]  # the walk sees imports
    assert cycles(graph) == []


def test_a_planted_cycle_is_found() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(graph) == [["a", "b", "c"]]


@pytest.mark.parametrize(
    ("module", "names"),
    [
        ("sb3_maddpg.sharing", ["CriticFeaturesExtractor", "FullCriticFeatures", "SelectedCriticFeatures", "resolve_scheme"]),
        ("sb3_maddpg.sharing", ["AttentionCriticFeatures", "LearnedSelectionCriticFeatures", "LEARNED_SCHEMES"]),
    ],
)
def test_the_sharing_package_exports_its_schemes(module: str, names: list[str]) -> None:
    imported = __import__(module, fromlist=names)
    assert all(hasattr(imported, name) for name in names)


LAYERS = [
    ("sb3_maddpg.__main__", ()),  # `python -m sb3_maddpg`: the command line's entry
    ("sb3_maddpg.cli", ("sb3_maddpg.__main__",)),
    ("sb3_maddpg.tuning", ("sb3_maddpg.__main__", "sb3_maddpg.cli")),
    ("sb3_maddpg.results", ("sb3_maddpg.__main__", "sb3_maddpg.cli", "sb3_maddpg.tuning")),
    ("sb3_maddpg.experiments", ("sb3_maddpg.__main__", "sb3_maddpg.cli", "sb3_maddpg.tuning", "sb3_maddpg.results")),
]
"""The study's packages (and the command line's entry) from the top down, each with the packages it must not import:
those above it. Everything else in the package (the library: algorithms, sharing schemes, envs, run groups, analysis,
hyperparameters) must import none of them."""

STUDY = tuple(package for package, _ in LAYERS)


def in_package(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def layering_violations(graph: dict[str, set[str]]) -> list[str]:
    """:return: ``"importer -> imported"`` for each import that reaches up: from the library into the study, or from a
    study package into one above it."""
    found = []
    for module, targets in sorted(graph.items()):
        home = next((package for package in STUDY if in_package(module, package)), None)
        forbidden = dict(LAYERS)[home] if home else STUDY
        if module == "sb3_maddpg":  # the package's own __init__ re-exports the library only; it is checked as the library
            forbidden = STUDY
        found += [f"{module} -> {target}" for target in sorted(targets) if any(in_package(target, up) for up in forbidden)]
    return found


def test_the_library_imports_no_study_package_and_each_study_package_none_above_it() -> None:
    graph = package_imports()
    assert {"sb3_maddpg.results.report", "sb3_maddpg.tuning.search", "sb3_maddpg.cli.main"} <= set(graph)
    assert layering_violations(graph) == []


def test_a_planted_upward_import_is_found() -> None:
    graph = {
        "sb3_maddpg.hyperparams": {"sb3_maddpg.experiments.config"},
        "sb3_maddpg.experiments.runner": {"sb3_maddpg.results.stats", "sb3_maddpg.maddpg"},
        "sb3_maddpg.results.report": {"sb3_maddpg.experiments.config"},
    }
    assert layering_violations(graph) == [
        "sb3_maddpg.experiments.runner -> sb3_maddpg.results.stats",
        "sb3_maddpg.hyperparams -> sb3_maddpg.experiments.config",
    ]


def test_the_console_script_names_the_command_lines_main() -> None:
    """``sb3-maddpg`` is setup.cfg's entry point: the function it names must exist (a moved module breaks the
    installed command without any import in the package failing)."""
    import configparser
    import importlib

    config = configparser.ConfigParser()
    config.read(PACKAGE.parent / "setup.cfg")
    lines = config["options.entry_points"]["console_scripts"].strip().splitlines()
    scripts = {name.strip(): target.strip() for name, target in (line.split("=", 1) for line in lines)}
    module, _, function = scripts["sb3-maddpg"].partition(":")
    assert callable(getattr(importlib.import_module(module), function))
