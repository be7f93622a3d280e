"""The code's structure (issue 26): the modules' imports, lazy ones included, form no circle, go
through the one package and take no other module's private names; no function of sim/ takes more
than seven positional parameters."""
import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "logs", "proto", "replay", "scenarios", "bench", "view", "service", "sweep")


def _graph() -> dict[str, set[str]]:
    files = {"cli": ROOT / "cli.py"}
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            files[name.removesuffix(".__init__")] = path

    def resolve(name: str) -> str | None:
        name = name.removeprefix("touchdown.")
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for mod, path in files.items():
        out = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            else:
                continue
            out |= {r for r in map(resolve, names) if r and r != mod}
        graph[mod] = out
    return graph


def _circles(graph: dict[str, set[str]]) -> set[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan's)."""
    index, low, stack, on, found = {}, {}, [], set(), set()

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.add(frozenset(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_import_circles():
    graph = _graph()
    assert "cli" not in graph["bench.fuzz"] and "sim.measure" not in graph["sim.params"]
    # nothing but cli.py imports cli.py: the command line is the top (the atheris harness records
    # its seed logs through the library)
    assert {mod for mod, deps in graph.items() if "cli" in deps} == set()
    assert not _circles(graph), _circles(graph)


def test_no_private_name_crosses_modules():
    """A name that starts with one underscore is its module's own: no other module imports it or
    reaches it through the module (``verify._first_difference`` had been used by the incident
    report; issue 26)."""
    files = {"cli": ROOT / "cli.py"}
    for pkg in PACKAGES:
        files |= {str(p): p for p in (ROOT / pkg).rglob("*.py")}
    crossings = []
    for path in files.values():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        modules = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                    and node.module.startswith("touchdown."):
                for a in node.names:
                    if a.name.startswith("_") and not a.name.startswith("__"):
                        crossings.append(f"{path.name}: from {node.module} import {a.name}")
                    modules.add(a.asname or a.name)
            elif isinstance(node, ast.Import):
                modules |= {a.asname or a.name for a in node.names
                            if a.name.startswith("touchdown.")}
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                    and node.value.id in modules and node.attr.startswith("_") \
                    and not node.attr.startswith("__"):
                crossings.append(f"{path.name}: {node.value.id}.{node.attr}")
    assert not crossings, crossings


@pytest.mark.slow
def test_one_installed_package_and_every_module_imports_through_it(tmp_path):
    """The install puts one name, ``touchdown``, where Python looks for modules (issue 26: a wheel
    had put ``sim``, ``logs``, ``cli`` ... beside every other project's); every module of the
    repository imports the others as ``touchdown.PART``."""
    bare = []
    for pkg in (*PACKAGES, "cli"):
        for path in [ROOT / "cli.py"] if pkg == "cli" else (ROOT / pkg).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                         [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0
                         and node.module else [])
                bare += [f"{path.name}: {n}" for n in names
                         if n.split(".")[0] in (*PACKAGES, "cli")]
    assert not bare, bare
    graph = _graph()
    assert "sim.step" in graph["sim.world"] and "logs.writer" in graph["logs.rotating"]
    probe = ("import importlib.util as u, touchdown.cli, touchdown.sim.step; "
             "print([n for n in ('sim', 'logs', 'proto', 'replay', 'scenarios', 'bench', 'view', "
             "'service', 'sweep', 'cli') if u.find_spec(n) is not None])")
    out = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "[]"


def _long_signatures(source: str, limit: int = 7) -> list[str]:
    """The functions (and methods) defined in ``source`` that take more than ``limit`` positional
    parameters, each as "name (count)"."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            n = len(node.args.posonlyargs) + len(node.args.args)
            if n > limit:
                found.append(f"{node.name} ({n})")
    return found


def test_no_function_of_sim_takes_more_than_seven_positional_parameters():
    """Arguments that travel together are passed together (issue 26: a contact evaluation took 16
    loose numbers, the friction solve 16, the energy 14; issue 38: 14 functions took 8 or 9): a
    ship's Motion, its Legs and their Dampers, a foot's Spring, the Body, the FrictionLaw, the
    FrictionForce carried into a step, the Holding feet, the Rigid body friction moves, the feet
    on the ground (FeetOn), where a step starts (StepFrom), a piece's and a sub-step's start, the
    Grounds of measured rows. No function defined in sim/ takes more than 7 positional
    parameters."""
    assert _long_signatures("def f(a, b, c, d, e, f, g, h, *, k=0):\n    pass\n") \
        == ["f (8)"]
    assert _long_signatures("class C:\n    def m(self, a, b, c, d, e, f, /, g):\n"
                            "        pass\n") == ["m (8)"]
    assert _long_signatures("def f(a, b, c, d, e, f, g, *rest, k=0):\n    pass\n") == []
    long = [f"sim/{path.name}: {name}" for path in sorted((ROOT / "sim").glob("*.py"))
            for name in _long_signatures(path.read_text(encoding="utf-8"))]
    assert not long, long
