"""Code quality gates that CI runs with the tests, the same for pipeline/ and stages/: ruff
(lint, import order, cyclomatic complexity ≤ 10), mypy over the package as installed (every
function typed, the kind contract strict), the size of modules, and an import graph without
a circle."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from support.places import REPO

BIN = Path(sys.executable).parent


def _tool(name: str) -> str:
    exe = BIN / name
    if not exe.exists():
        pytest.fail(f"{name} is not installed beside the test interpreter; install the [test] extra")
    return str(exe)


def test_ruff_lint_and_complexity():
    out = subprocess.run(
        [_tool("ruff"), "check", "pipeline", "stages", "tests"], cwd=REPO, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stdout + out.stderr


def _installed_layout(root: Path) -> Path:
    """A folder ``ftsweep`` under ``root`` laid out as the package installs (pipeline/'s entries,
    stages/ as ftsweep/stages), by links, so that mypy follows every ``ftsweep.`` import."""
    package = root / "ftsweep"
    package.mkdir()
    for entry in (REPO / "pipeline").iterdir():
        if entry.name != "__pycache__":
            (package / entry.name).symlink_to(entry)
    (package / "stages").symlink_to(REPO / "stages")
    return root


@pytest.mark.integration  # mypy over the package
def test_mypy_every_function_typed_and_the_kind_contract_strict(tmp_path):
    """mypy over the package as installed (pyproject's settings: every function typed; the
    contract, the registry and the kinds with --strict's flags)."""
    env = dict(os.environ, MYPYPATH=str(_installed_layout(tmp_path)))
    out = subprocess.run(
        [_tool("mypy"), "--no-error-summary", "--cache-dir", str(tmp_path / "cache"), "-p", "ftsweep"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert out.returncode == 0, out.stdout + out.stderr


MAX_MODULE_LINES = 600
MAX_COMPLEXITY = 10


def test_modules_stay_small_and_functions_simple():
    """Modules by responsibility: none of pipeline/ or stages/ over 600 lines. Functions by
    their branches, not their lines (docs/architecture.md, "Sizes"): ruff's McCabe check
    (C901) is on at a cyclomatic complexity of 10, which test_ruff_clean then enforces."""
    import tomllib

    too_long = []
    for path in sorted([*(REPO / "pipeline").rglob("*.py"), *(REPO / "stages").rglob("*.py")]):
        lines = len(path.read_text(encoding="utf-8").splitlines())
        if lines > MAX_MODULE_LINES:
            too_long.append(f"{path.relative_to(REPO)}: {lines} lines")
    assert not too_long, too_long
    lint = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["ruff"]["lint"]
    assert "C90" in lint["select"] and lint["mccabe"]["max-complexity"] == MAX_COMPLEXITY


def _module_names() -> dict[str, Path]:
    """Every module of the package by its import name (``pipeline/`` is ``ftsweep``,
    ``stages/`` is ``ftsweep.stages``)."""
    names = {}
    for root, base in (("pipeline", "ftsweep"), ("stages", "ftsweep.stages")):
        for path in (REPO / root).rglob("*.py"):
            parts = list(path.relative_to(REPO / root).with_suffix("").parts)
            names[".".join([base, *(parts[:-1] if parts[-1] == "__init__" else parts)])] = path
    return names


def _imports(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The package's modules ``name`` imports anywhere in its text (inside functions too,
    where a lazy import would hide a circle from a run-time check)."""
    import ast

    package = name.split(".") if path.stem == "__init__" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
            low[v] = min(low[v], low[w] if w in stack or w not in index else low[v])
        if low[v] == index[v]:
            component = stack[stack.index(v) :]
            del stack[stack.index(v) :]
            if len(component) > 1:
                circles.append(sorted(component))

    for name in graph:
        if name not in index:
            visit(name)
    return circles


def test_no_circle_of_imports():
    """The import graph of ftsweep's modules has no circle, counting the imports inside
    functions and those for annotations only; the registry reaches the kinds through entry
    points, which are not imports."""
    known = _module_names()
    graph = {name: _imports(name, path, known) for name, path in known.items()}
    assert len(graph) > 50 and sum(map(len, graph.values())) > 200  # the walk did find the imports
    assert not _circles(graph)


def _room(module: str) -> str:
    """The room a module sits in: a stage (``ftsweep.stages.paths``), a kind
    (``ftsweep.kinds.spiral``), a folder of pipeline/ or a top-level module; ``ftsweep`` is the face."""
    parts = module.split(".")
    return ".".join(parts[:3] if parts[1:2] in (["stages"], ["kinds"]) else parts[:2])


def test_no_two_rooms_import_each_other_and_none_imports_the_face():
    """Rooms, not only modules, form no circle (a stage that imports another imports nothing
    of it back), and no module imports the package face ``ftsweep``, which stands above all."""
    known = _module_names()
    rooms: dict[str, set[str]] = {}
    for name, path in known.items():
        if name == "ftsweep":
            continue
        for target in _imports(name, path, known):
            if _room(target) != _room(name):
                rooms.setdefault(_room(name), set()).add(_room(target))
    assert len(rooms) > 20 and "ftsweep.stages.paths" in rooms
    assert not [room for room, targets in rooms.items() if "ftsweep" in targets]
    everything = set(rooms) | {t for targets in rooms.values() for t in targets}
    assert not _circles({room: rooms.get(room, set()) for room in everything})


def test_the_circle_finder_finds_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _circles(graph) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


# the layers of docs/architecture.md, lowest first: a module imports its own layer's modules
# and those below, never above (function-level imports count); ``ftsweep`` itself is the face
LAYERS = (
    ("stages", ("ftsweep.stages",)),
    (
        "base",
        (
            "ftsweep.version",
            "ftsweep.errors",
            "ftsweep.defaults",
            "ftsweep.freetext",
            "ftsweep.progress",
            "ftsweep.caches",
        ),
    ),
    ("inputs", ("ftsweep.inputs",)),
    ("engine", ("ftsweep.engine", "ftsweep.simulate")),
    ("store and export formats", ("ftsweep.store", "ftsweep.exports", "ftsweep.options")),
    ("kinds", ("ftsweep.kinds",)),
    ("registry", ("ftsweep.registry",)),
    ("sweeps", ("ftsweep.sweeps",)),
    ("tools", ("ftsweep.tools",)),
    ("cli", ("ftsweep.cli",)),
    ("testing", ("ftsweep.testing",)),
)
GENERIC = ("engine", "store and export formats", "registry", "sweeps", "tools", "cli", "inputs", "base")


def _layer(module: str) -> int:
    """The index of ``module``'s layer in :data:`LAYERS` (the face ``ftsweep`` is above all)."""
    if module == "ftsweep":
        return len(LAYERS)
    found = [
        (len(p), i)
        for i, (_, prefixes) in enumerate(LAYERS)
        for p in prefixes
        if module == p or module.startswith(p + ".")
    ]
    assert found, f"{module} is in no layer of docs/architecture.md"
    return max(found)[1]


def _upward(graph: dict[str, set[str]]) -> list[str]:
    """Every import that points up a layer, and every import of one kind's subpackage by another's."""
    found = []
    for name, targets in graph.items():
        for target in sorted(targets):
            if target != "ftsweep" and _layer(target) > _layer(name):
                found.append(
                    f"{name} ({LAYERS[_layer(name)][0]}) imports {target} ({LAYERS[_layer(target)][0]})"
                )
            own, other = name.split(".")[:3], target.split(".")[:3]
            if own[:2] == other[:2] == ["ftsweep", "kinds"] and len(own) == len(other) == 3 and own != other:
                found.append(f"the kind {own[2]} imports the kind {other[2]} ({target})")
    return found


def test_every_import_points_down_the_layers():
    """docs/architecture.md's layer order holds for every import of every module, those inside
    functions included: nothing reaches up, and no kind leans on another kind."""
    known = _module_names()
    graph = {name: _imports(name, path, known) for name, path in known.items()}
    assert sum(map(len, graph.values())) > 300  # the walk did find the imports
    assert not _upward(graph)


def test_the_layer_check_finds_an_arrow_up():
    graph = {
        "ftsweep.engine.case": {"ftsweep.registry"},
        "ftsweep.kinds.dpath.kind": {"ftsweep.kinds.spiral.format", "ftsweep.engine.case"},
        "ftsweep.cli.main": {"ftsweep.stages.envelope.arcs"},
    }
    assert _upward(graph) == [
        "ftsweep.engine.case (engine) imports ftsweep.registry (registry)",
        "the kind dpath imports the kind spiral (ftsweep.kinds.spiral.format)",
    ]


def _kind_names() -> set[str]:
    from ftsweep import registry

    folders = {p.name for p in (REPO / "pipeline" / "kinds").iterdir() if (p / "__init__.py").exists()}
    return set(registry.names()) | folders


def test_generic_modules_name_no_kind():
    """No generic module (engine, store, exports, sweeps, tools, cli, inputs, the registry) names
    a kind, by import or by a string equal to a kind's name or folder: they ask the registry."""
    import ast

    known = _module_names()
    names = _kind_names()
    assert {"ring", "mesh", "spiral", "dpath", "fresnel", "table"} <= names
    offenders = []
    for module, path in known.items():
        if LAYERS[min(_layer(module), len(LAYERS) - 1)][0] not in GENERIC or module == "ftsweep":
            continue
        offenders += [
            f"{module} imports {t}" for t in _imports(module, path, known) if t.startswith("ftsweep.kinds")
        ]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
                offenders.append(f"{module}:{node.lineno} names the kind {node.value!r}")
    assert not offenders


def _texts_shown(tree: Any) -> Iterator[tuple[int, str]]:
    """The strings of a module a user reads or a kind could hide in: module-level literals
    (in tables and tuples too), every ``help=`` text and the docstrings of click commands."""
    import ast

    def strings(node: Any) -> Iterator[tuple[int, str]]:
        for c in ast.walk(node):
            if isinstance(c, ast.Constant) and isinstance(c.value, str):
                yield c.lineno, c.value

    for node in tree.body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
            yield from strings(node.value)
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == "help":
            yield from strings(node.value)
        elif isinstance(node, ast.FunctionDef) and any(
            "command" in ast.unparse(d) or "group" in ast.unparse(d) for d in node.decorator_list
        ):
            doc = ast.get_docstring(node)
            if doc:
                yield node.body[0].lineno, doc


def _kind_words(source: str, names: set[str]) -> list[str]:
    """``line: word`` for every kind name a module's shown strings hold as a word (a catalog
    entry's name such as ``sinewave-ring`` or a path is not the word)."""
    import ast
    import re

    alternatives = "|".join(sorted(map(re.escape, names), key=len, reverse=True))
    word = re.compile(r"(?<![\w/.-])(" + alternatives + r")(?:e?s)?(?![\w/-]|\.\w)", re.I)
    return [
        f"{line}: {m.group(0)}" for line, text in _texts_shown(ast.parse(source)) for m in word.finditer(text)
    ]


def test_generic_modules_word_no_kind_in_what_they_show():
    """Nor does a generic module name a kind inside its module-level literals, help texts or
    command docstrings: the help a user reads of the kinds comes from the kinds themselves
    (``description``, ``exports_as``, ``predict_help``, ``examples``)."""
    from ftsweep import registry

    names = set(registry.names())
    offenders = []
    for module, path in _module_names().items():
        if LAYERS[min(_layer(module), len(LAYERS) - 1)][0] not in GENERIC or module == "ftsweep":
            continue
        offenders += [f"{module}:{hit}" for hit in _kind_words(path.read_text(encoding="utf-8"), names)]
    assert not offenders


def test_the_kind_word_gate_finds_a_kind_in_help_and_literals():
    source = (
        'ROWS = ("predict a 5k ring",)\nNAME = "sinewave-ring"\n'
        '@click.command()\n@click.option("--x", help="Language of a spiral program")\n'
        'def cmd():\n    """Compare meshes."""\n'
        'def inner():\n    return "a ring inside a function is not shown"\n'
    )
    assert sorted(_kind_words(source, {"ring", "spiral", "mesh"})) == ["1: ring", "4: spiral", "6: meshes"]


STAGES = (
    "sampling",
    "layouts",
    "interpolation",
    "envelope",
    "metrics",
    "kinematics",
    "paths",
    "numerics",
    "measurement",
)


def test_the_stage_faces_export_their_kernels_and_load_them_only_when_used():
    """Each stage's face names its public kernels and modules in ``__all__``; every name loads
    from its module, and importing every face loads none of its modules."""
    import importlib
    import json

    assert sorted(STAGES) == sorted(
        p.name for p in (REPO / "stages").iterdir() if (p / "__init__.py").exists()
    )
    for stage in STAGES:
        face = importlib.import_module(f"ftsweep.stages.{stage}")
        assert face.__all__ and face.__doc__
        for name in face.__all__:
            assert getattr(face, name) is not None, f"ftsweep.stages.{stage}.{name}"
        with pytest.raises(AttributeError):
            face.no_such_kernel  # noqa: B018
    probe = (
        "import json, sys\n"
        + "".join(f"import ftsweep.stages.{s}\n" for s in STAGES)
        + "print(json.dumps(sorted(m for m in sys.modules if m.startswith('ftsweep.stages.'))))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == sorted(f"ftsweep.stages.{s}" for s in STAGES)


def test_the_rooms_faces_export_their_public_names():
    """``ftsweep.engine``, ``store``, ``exports``, ``inputs``, ``sweeps`` and ``tools`` name their
    public names in ``__all__``, each loading from its module, and no name hides a module's."""
    import importlib

    for room in ("engine", "store", "exports", "inputs", "sweeps", "tools"):
        face = importlib.import_module(f"ftsweep.{room}")
        assert face.__all__, room
        for name in face.__all__:
            assert not (REPO / "pipeline" / room / f"{name}.py").exists(), f"ftsweep.{room}.{name}"
            assert getattr(face, name) is not None, f"ftsweep.{room}.{name}"


# the repository's top level, as the README's layout lists it: nothing stray (a committed
# wheel, a scratch file) reaches a clone
TOP_LEVEL = {
    ".ci",
    ".gitignore",
    "LICENSE",
    "README.md",
    "catalogs",
    "docs",
    "outputs",
    "pipeline",
    "pyproject.toml",
    "stages",
    "tests",
}


def test_every_package_folder_is_one_the_wheel_lists():
    """pyproject.toml names the packages a wheel holds one by one: a folder with an
    ``__init__.py`` that it does not name would be missing from every regular install."""
    import tomllib

    tool = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(tool["packages"])
    folders = {"pipeline": "ftsweep", "stages": "ftsweep.stages"}
    found = {
        ".".join([root, *init.parent.relative_to(REPO / top).parts])
        for top, root in folders.items()
        for init in (REPO / top).rglob("__init__.py")
    }
    assert len(found) > 20
    assert found <= listed, sorted(found - listed)


def test_nothing_stray_is_committed_at_the_top_level():
    listed = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True)
    if listed.returncode != 0:
        pytest.skip(f"not a git checkout ({listed.stderr.strip()[:80]}): the tracked files are unknown")
    tops = {line.split("/", 1)[0] for line in listed.stdout.splitlines() if line}
    assert tops <= TOP_LEVEL, f"stray at the top level: {sorted(tops - TOP_LEVEL)}"
    assert not [f for f in listed.stdout.splitlines() if f.endswith((".whl", ".tar.gz", ".zip"))]
