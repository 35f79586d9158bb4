"""The package layout: folders import only folders under them, no circles.

The rooms, from the bottom up (README's module table): the folder
``meshes`` and, beside it, the top-level modules ``assembly`` and ``forms``
(two rooms of rank 0, neither importing the other); ``approximation`` (RK
functions); ``mechanics`` (physics on any basis); ``solvers``; then
``verification`` and ``runs``, which use everything below and not each other.
A module may import modules of its own folder and of folders of a lower
rank.  Every import counts, also those inside functions.
"""

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "skfem_rkpm"

RANK = {"": 0, "meshes": 0, "approximation": 1, "mechanics": 2, "solvers": 3,
        "verification": 4, "runs": 4}

OPTIONAL = ("numba", "dask", "distributed", "pypardiso", "sksparse", "pyamg", "cvxopt",
            "petsc4py", "mpi4py", "hypothesis", "pytest")


def module_name(path):
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_modules():
    """``{module name: (path, source)}`` of the package, its ``__init__`` left out."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        source = path.read_text()
        name = module_name(path)
        if name == "skfem_rkpm":
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


def test_the_checker_sees_a_mesh_module_importing_a_top_level_module():
    """meshes and the top-level modules share rank 0: an import between them
    is sideways, and refused."""
    source = "from ..assembly import layout\n"
    path = PACKAGE / "meshes" / "example.py"
    targets = imported_modules("skfem_rkpm.meshes.example", path, source)
    assert targets == {"skfem_rkpm.assembly"}
    a, b = folder("skfem_rkpm.meshes.example"), folder("skfem_rkpm.assembly")
    assert (a, b) == ("meshes", "") and RANK[b] >= RANK[a]


def test_importing_the_package_loads_no_optional_dependency():
    code = ("import sys, skfem_rkpm\n"
            f"print(' '.join(m for m in {OPTIONAL!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "", f"import skfem_rkpm loads the optional packages {out}"


def test_no_module_forwards_its_names():
    """No module (the package's ``__init__`` included) hands attribute
    look-ups to other modules through a module-level ``__getattr__``: each
    name is found in the module whose path it is imported from."""
    forwarding = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.parse(path.read_text()).body:
            names = ([node.name] if isinstance(node, ast.FunctionDef)
                     else [t.id for n in ([node] if isinstance(node, ast.Assign) else [])
                           for t in ast.walk(n) if isinstance(t, ast.Name)
                           and isinstance(t.ctx, ast.Store)])
            if "__getattr__" in names:
                forwarding.append(str(path.relative_to(PACKAGE.parent)))
    assert not forwarding, f"modules with a module-level __getattr__: {forwarding}"
