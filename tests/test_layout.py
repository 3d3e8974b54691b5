"""The package's house rules, read from its source with ast: no import cycle between
modules, no private name imported from another module, imports inside functions only
for optional dependencies, and tests that import nothing from scripts/."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "nlp"
# Imported where they are used so that the package works without them (extras in pyproject).
OPTIONAL = {"dask", "distributed", "openseespy", "pyuff", "pdoc"}
# nlp/__init__.py loads its API on first use (PEP 562) so that `import nlp` stays light.
LAZY = {("nlp", "__getattr__")}


def _modules(pkg=PKG):
    mods = {}
    for path in sorted(pkg.rglob("*.py")):
        parts = list(path.relative_to(pkg.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        mods[".".join(parts)] = path
    return mods


def _target(mod, path, node):
    """The absolute module named by an ImportFrom node inside module ``mod``."""
    if not node.level:
        return node.module
    base = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
    base = base[:len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(mods):
    """(module, imported module, imported name or None, enclosing function or None)."""
    out = []
    for mod, path in mods.items():
        tree = ast.parse(path.read_text())
        parents = {}
        for node in ast.walk(tree):
            for child in ast.iter_child_nodes(node):
                parents[child] = node

        def function_of(node):
            while node in parents:
                node = parents[node]
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    return node.name
            return None

        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                tgt = _target(mod, path, node)
                for alias in node.names:
                    out.append((mod, tgt, alias.name, function_of(node)))
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    out.append((mod, alias.name, None, function_of(node)))
    return out


MODS = _modules()
IMPORTS = _imports(MODS)


def _edges():
    edges = {m: set() for m in MODS}
    for mod, tgt, name, fn in IMPORTS:
        if tgt is None or tgt.split(".")[0] != "nlp" or (mod, fn) in LAZY:
            continue  # a lazy import runs after its module has loaded: no cycle at import
        full = f"{tgt}.{name}" if name else tgt
        edges[mod].add(full if full in MODS else tgt)
    return edges


def _cycles(edges):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, comps = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
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
                comps.append(sorted(comp))

    for v in edges:
        if v not in index:
            visit(v)
    return comps


def test_the_checker_finds_a_cycle_and_a_private_import(tmp_path):
    pkg = tmp_path / "nlp"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "a.py").write_text("from nlp.sub.b import _hidden\n")
    (pkg / "sub" / "b.py").write_text("from . import a\n\ndef f():\n    import numpy\n")
    mods = _modules(pkg)
    imports = _imports(mods)
    assert ("nlp.sub.a", "nlp.sub.b", "_hidden", None) in imports
    assert ("nlp.sub.b", "nlp.sub", "a", None) in imports
    assert ("nlp.sub.b", "numpy", None, "f") in imports
    edges = {m: set() for m in mods}
    for mod, tgt, name, _ in imports:
        if tgt.startswith("nlp"):
            full = f"{tgt}.{name}"
            edges[mod].add(full if full in mods else tgt)
    assert _cycles(edges) == [["nlp.sub.a", "nlp.sub.b"]]


def test_no_import_cycle():
    assert _cycles(_edges()) == []


def test_no_private_name_imported_from_another_module():
    bad = [f"{mod} imports {name} from {tgt}" for mod, tgt, name, _ in IMPORTS
           if tgt and tgt.startswith("nlp") and name and name.startswith("_")
           and not name.startswith("__")]
    assert bad == []


def test_imports_inside_functions_only_for_optional_dependencies():
    bad = [f"{mod}.{fn} imports {tgt}{'.' + name if name and tgt == 'nlp' else ''}"
           for mod, tgt, name, fn in IMPORTS
           if fn is not None and (mod, fn) not in LAZY
           and (tgt or "").split(".")[0] not in OPTIONAL]
    assert bad == []


@pytest.mark.parametrize("folder", ["tests", "nlp"])
def test_nothing_imports_from_scripts_or_research(folder):
    local = {p.stem for d in ("scripts", "research") if (ROOT / d).is_dir()
             for p in (ROOT / d).glob("*.py")}
    bad = []
    for path in (ROOT / folder).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module] if isinstance(node, ast.ImportFrom) and not node.level
                     else [])
            bad += [f"{path.relative_to(ROOT)}: {n}" for n in names
                    if n and n.split(".")[0] in local | {"scripts", "research"}]
            if (isinstance(node, ast.Attribute) and node.attr in ("insert", "append")
                    and ast.unparse(node.value) == "sys.path" and path.name != "conftest.py"):
                bad.append(f"{path.relative_to(ROOT)}: edits sys.path")
    assert bad == []


def test_import_nlp_has_no_side_effect():
    code = ("import os, sys; before = dict(os.environ); import nlp; "
            "assert dict(os.environ) == before; assert 'numpy' not in sys.modules; "
            "assert callable(nlp.run) and callable(nlp.load_case)")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, env=env)


def test_the_api_runs_blas_on_one_thread_unless_the_user_chose():
    code = ("import numpy, threadpoolctl; from nlp.solve.executors.threads import one_blas_thread\n"
            "n = lambda: max(i['num_threads'] for i in threadpoolctl.threadpool_info()"
            " if i['user_api'] == 'blas')\n"
            "with one_blas_thread(): print(n())\n")
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS",
                                                              "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    got = subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, env=env,
                         capture_output=True, text=True).stdout.split()
    assert got == ["1"]
    env["OPENBLAS_NUM_THREADS"] = "2"
    got = subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, env=env,
                         capture_output=True, text=True).stdout.split()
    assert got == ["2"]


MODULE_LINES, FUNCTION_LINES = 500, 80
# Longer pieces that read better whole, each with its reason (docs/architecture.md).
LONG = {}


def test_modules_and_functions_stay_small():
    long = []
    for mod, path in MODS.items():
        text = path.read_text()
        if text.count("\n") > MODULE_LINES and mod not in LONG:
            long.append(f"{mod}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > FUNCTION_LINES and f"{mod}.{node.name}" not in LONG:
                    long.append(f"{mod}.{node.name}: {n} lines")
    assert long == []
