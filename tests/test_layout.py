"""The package layout: folders import only folders under them, no circles.

The rooms, from the bottom up (docs/../DESIGN picture, README's module
table): the top-level modules ``meshes`` and ``assembly``; ``approximation``
(RK functions); ``mechanics`` (physics on any basis); ``solvers``; then
``verification`` and ``runs``, which use everything below and not each other.
A module may import modules of its own folder and of folders of a lower
rank.  Every import counts, also those inside functions.  The forwarding
modules of the old flat layout (``skfem_rkpm/basis.py`` and the like) are
left out: they exist to point at the new places.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "skfem_rkpm"

RANK = {"": 0, "approximation": 1, "mechanics": 2, "solvers": 3,
        "verification": 4, "runs": 4}

OPTIONAL = ("numba", "dask", "distributed", "pypardiso", "sksparse", "pyamg", "cvxopt",
            "petsc4py", "mpi4py", "hypothesis", "pytest")


def module_name(path):
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def is_forwarding(source):
    return "forward(__name__" in source


def package_modules():
    """``{module name: (path, source)}`` of the package, forwarding modules left out."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        source = path.read_text()
        name = module_name(path)
        if name in ("skfem_rkpm", "skfem_rkpm._moved") or is_forwarding(source):
            continue
        modules[name] = (path, source)
    return modules


def imported_modules(name, path, source):
    """Names of the skfem_rkpm modules that ``source`` imports, anywhere in it."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("skfem_rkpm"))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not target.startswith("skfem_rkpm"):
                continue
            for alias in node.names:  # `from .pkg import module`
                candidate = f"{target}.{alias.name}"
                found.add(candidate if _exists(candidate) else target)
    return found


def _exists(module):
    rel = Path(*module.split(".")[1:])
    return ((PACKAGE / rel).with_suffix(".py").exists()
            or (PACKAGE / rel / "__init__.py").exists())


def folder(module):
    """The room of a module: its sub-folder of the package, "" at the top."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and (PACKAGE / parts[1]).is_dir() else ""


def graph():
    modules = package_modules()
    return {name: {m for m in imported_modules(name, *modules[name]) if m in modules}
            for name in modules}


def test_every_folder_has_a_rank():
    folders = {folder(m) for m in package_modules()}
    assert folders <= set(RANK), f"folders without a rank: {folders - set(RANK)}"


def test_folders_import_only_folders_under_them():
    wrong = []
    for module, targets in graph().items():
        for target in targets:
            a, b = folder(module), folder(target)
            if a != b and RANK[b] >= RANK[a]:
                wrong.append(f"{module} imports {target}")
    assert not wrong, "upward or sideways imports:\n" + "\n".join(sorted(wrong))


def test_no_import_circles():
    edges = graph()
    state, circles = {}, []

    def visit(node, path):
        state[node] = "open"
        for nxt in sorted(edges[node]):
            if state.get(nxt) == "open":
                circles.append(" -> ".join(path[path.index(nxt):] + [nxt]))
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"

    for node in sorted(edges):
        if node not in state:
            visit(node, [node])
    assert not circles, "import circles:\n" + "\n".join(circles)


def test_the_checker_sees_an_upward_import(tmp_path):
    """The rule test fails on an approximation module that imports a solver."""
    source = "from ..solvers.linear import make_solver\n"
    path = PACKAGE / "approximation" / "example.py"
    targets = imported_modules("skfem_rkpm.approximation.example", path, source)
    assert targets == {"skfem_rkpm.solvers.linear"}
    assert RANK[folder("skfem_rkpm.solvers.linear")] > RANK["approximation"]


def test_importing_the_package_loads_no_optional_dependency():
    code = ("import sys, skfem_rkpm\n"
            f"print(' '.join(m for m in {OPTIONAL!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "", f"import skfem_rkpm loads the optional packages {out}"


@pytest.mark.parametrize("old, new, name", [
    ("skfem_rkpm.basis", "skfem_rkpm.approximation.basis", "RKBasis"),
    ("skfem_rkpm.linsolve", "skfem_rkpm.solvers.constrained", "solve_saddle_point"),
    ("skfem_rkpm.solver", "skfem_rkpm.solvers.newton", "newton_steps"),
    ("skfem_rkpm.runner", "skfem_rkpm.runs.runner", "run"),
    ("skfem_rkpm.mechanics.contact", "skfem_rkpm.runs.build", "from_scene"),
])
def test_old_paths_forward_with_a_deprecation_warning(old, new, name):
    code = ("import importlib, warnings\n"
            "with warnings.catch_warnings(record=True) as caught:\n"
            "    warnings.simplefilter('always')\n"
            f"    old = importlib.import_module({old!r})\n"
            f"obj = getattr(old, {name!r})\n"
            f"new = importlib.import_module({new!r})\n"
            "print(any(issubclass(w.category, DeprecationWarning) and "
            f"{new!r} in str(w.message) for w in caught))\n"
            f"print(obj is getattr(new, {name!r}, None) or obj.__module__ == {new!r})\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["True", "True"]
