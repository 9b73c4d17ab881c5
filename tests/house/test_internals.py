"""No dependency's internals are patched: in pipeline/ and stages/ no attribute of another
package's module or class is assigned or deleted, ``sys.meta_path`` and ``sys.path_hooks``
are left alone, no private attribute (``_name``) of another package is read, and no process
leaves by ``os._exit``. A dependency's minor release can change any of them silently."""

from __future__ import annotations

import ast
import sys

import pytest
from support.places import REPO

HOOKS = {"meta_path", "path_hooks", "path_importer_cache"}


def _outside(tree: ast.Module) -> tuple[set[str], set[str]]:
    """Names a module binds to other packages' objects by import: (all of them, those of
    third-party packages, i.e. neither the standard library nor ftsweep)."""
    names: set[str] = set()
    third: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            bound = [((a.asname or a.name).split(".")[0], a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            bound = [(a.asname or a.name, node.module) for a in node.names]
        else:
            continue
        for name, module in bound:
            top = module.split(".")[0]
            if top != "ftsweep":
                names.add(name)
                if top not in sys.stdlib_module_names:
                    third.add(name)
    return names, third


def _root(node: ast.expr) -> str | None:
    while isinstance(node, (ast.Attribute, ast.Subscript, ast.Call)):
        node = node.func if isinstance(node, ast.Call) else node.value
    return node.id if isinstance(node, ast.Name) else None


def _aliases(tree: ast.Module, names: set[str]) -> set[str]:
    """``names`` and the names assigned from them (``cache = caching.Cache``), to a fixed point."""
    found = set(names)
    while True:
        more = {
            target.id
            for node in ast.walk(tree)
            if isinstance(node, ast.Assign)
            and isinstance(node.value, (ast.Attribute, ast.Name))
            and _root(node.value) in found
            for target in node.targets
            if isinstance(target, ast.Name) and target.id not in found
        }
        if not more:
            return found
        found |= more


def _assigned(node: ast.AST) -> list[ast.expr]:
    """The targets a statement assigns or deletes."""
    if isinstance(node, (ast.Assign, ast.Delete)):
        return node.targets
    if isinstance(node, (ast.AugAssign, ast.AnnAssign)):
        return [node.target]
    return []


def _private(name: object) -> bool:
    return isinstance(name, str) and name.startswith("_") and not name.startswith("__")


def _call_finding(node: ast.Call, names: set[str], third: set[str]) -> str | None:
    """``setattr``/``delattr`` on a third-party object, ``getattr`` of another package's private name."""
    if not isinstance(node.func, ast.Name) or not node.args or _root(node.args[0]) is None:
        return None
    if node.func.id in ("setattr", "delattr") and _root(node.args[0]) in third:
        return f"{node.func.id} on {ast.unparse(node.args[0])}"
    if node.func.id == "getattr" and len(node.args) > 1 and _root(node.args[0]) in names:
        attr = node.args[1]
        if isinstance(attr, ast.Constant) and _private(attr.value):
            return f"reads private {ast.unparse(node)}"
    return None


def patched_internals(source: str) -> list[str]:
    """What in ``source`` patches or reads another package's internals, one line each."""
    tree = ast.parse(source)
    names, third = _outside(tree)
    names, third = _aliases(tree, names), _aliases(tree, third)
    out: list[str] = []
    for node in ast.walk(tree):
        out += [
            f"{node.lineno}: assigns {ast.unparse(t)}"
            for t in _assigned(node)
            if isinstance(t, ast.Attribute) and _root(t) in third
        ]
        found = _call_finding(node, names, third) if isinstance(node, ast.Call) else None
        if isinstance(node, ast.Attribute) and _root(node) in names:
            if node.attr in HOOKS:
                found = f"touches {ast.unparse(node)}"
            elif _private(node.attr):
                found = f"reads private {ast.unparse(node)}"
        if found:
            out.append(f"{getattr(node, 'lineno', 0)}: {found}")
    return out


def test_no_dependencys_internals_are_patched_or_read():
    found = [
        f"{path.relative_to(REPO)}:{line}"
        for folder in ("pipeline", "stages")
        for path in sorted((REPO / folder).rglob("*.py"))
        for line in patched_internals(path.read_text(encoding="utf-8"))
    ]
    assert not found, "\n".join(found)


@pytest.mark.parametrize(
    "source",
    [
        "from numba.core import caching\ncache = caching.Cache\ncache.load_overload = f",
        "from numba.core.registry import CPUDispatcher\nCPUDispatcher.__call__ = f",
        "import numba\ndel numba.config.CACHE_DIR",
        "import xarray\nsetattr(xarray.Dataset, 'x', 1)",
        "import sys\nsys.meta_path.insert(0, finder)",
        "import sys\nsys.meta_path = []",
        "from xarray.namedarray import pycompat\ncache = pycompat._cached_duck_array_modules",
        "import numpy\nswitch = getattr(numpy, '_core', None)",
        "import os\nos._exit(0)",
        "import atexit\natexit._run_exitfuncs()",
    ],
)
def test_the_check_finds_each_kind_of_patch(source):
    assert patched_internals(source), source


@pytest.mark.parametrize(
    "source",
    [
        "import numpy as np\nspan[~np.isfinite(p)] = np.nan",
        "import os\nos.environ['X'] = '1'",
        "import warnings\nwarnings.formatwarning = one_line",  # documented as replaceable
        "from ftsweep import registry\nregistry._cache = {}",
        "import numpy as np\nclass A:\n    def f(self):\n        self.x = np.zeros(3)",
    ],
)
def test_the_check_leaves_supported_uses_alone(source):
    assert not patched_internals(source), source
