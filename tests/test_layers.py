"""The package's layers: every module of `dynabarn/` imports only its own layer and the
layers below it, and no modules import each other in a circle.

Read from the source (every `import`, also inside functions), so it holds for modules that
import lazily too. The layers are docs/architecture.md's "Layout".
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "dynabarn"

LAYERS: tuple[tuple[str, ...], ...] = (
    # foundations
    (
        "errors",
        "exports",
        "limits",
        "registry",
        "determinism",
        "files",
        "processes",
        "provenance",
        "robot",
        "protocol",
        "sim_config",
        "metrics",
        "metric_registry",
    ),
    ("interfaces",),  # what planners and observers are written against: no MuJoCo, no simulator
    ("worlds",),
    ("world_file",),  # a world file read, parsed and checked as untrusted input
    ("robot_mjcf", "mjcf"),  # the Jackal's MJCF model, then the worlds' (MuJoCo from here up)
    ("worldset",),
    ("sim",),
    ("perception",),  # what a robot makes of its laser: below the planners that use it
    ("planners",),
    ("recording",),
    ("runner",),  # one episode described and run one way: every command goes through it
    ("checks",),  # what a plugin author runs on a planner or tracker (`check_planner`, `check_tracker`)
    ("rerun_scene", "rerun_replay", "web_viewer"),  # consumers of the layers above, each may use the ones before it
    ("render",),
    ("live",),
    ("demos",),
    ("bench",),
    ("learn",),
    ("ros",),
    ("cli", "__main__"),
)
"""Bottom to top: the first dotted part below `dynabarn` names a module's layer."""


def _layer_of(module: str) -> int:
    parts = module.split(".")
    if parts == ["dynabarn"]:
        return len(LAYERS)  # the package's face: above everything
    for i, names in enumerate(LAYERS):
        if parts[1] in names:
            return i
    raise AssertionError(f"{module}: not in any declared layer; add it to LAYERS (and docs/architecture.md)")


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    return _imports_in(path.read_text(), _module_name(path))


def _imports_in(text: str, this: str) -> set[str]:
    """Every dynabarn module that the source imports (`from dynabarn.x import y` counts as
    x.y when x/y is a module, else x)."""
    tree = ast.parse(text)
    # Imports under `if TYPE_CHECKING:` are annotations, never run: not an edge.
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            node.body = []
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("dynabarn"))
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if not node.module.startswith("dynabarn"):
                continue
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                out.add(sub if _is_module(sub) else node.module)
    out.discard(this)
    return out


def _is_module(name: str) -> bool:
    base = PACKAGE.parent.joinpath(*name.split("."))
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
GRAPH = {m: _imports(p) for m, p in MODULES.items()}


def test_every_module_is_in_a_layer():
    assert len(MODULES) > 60
    for m in MODULES:
        _layer_of(m)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_only_go_down(module):
    own = _layer_of(module)
    up = sorted(i for i in GRAPH[module] if _layer_of(i) > own)
    assert not up, f"{module} (layer {LAYERS[own]}) imports from higher layers: {up}"


def test_no_import_circles():
    # A package's face (__init__) hands names on from its own modules; an edge into a face
    # stands for an edge into the module that defines the name, so faces are followed
    # through. Circles are searched among the remaining modules.
    faces = {m for m, p in MODULES.items() if p.name == "__init__.py"}

    def targets(m: str) -> set[str]:
        seen, out, stack = set(), set(), list(GRAPH[m])
        while stack:
            t = stack.pop()
            if t in seen:
                continue
            seen.add(t)
            if t in faces and t != m:
                stack.extend(GRAPH.get(t, ()))
            elif t in MODULES:
                out.add(t)
        return out - {m}

    edges = {m: targets(m) for m in MODULES if m not in faces}
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        path.append(m)
        for t in sorted(edges.get(m, ())):
            if state.get(t) == 1:
                raise AssertionError("import circle: " + " -> ".join([*path[path.index(t) :], t]))
            if t not in state and t in edges:
                visit(t)
        path.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)


def test_the_check_catches_an_upward_import():
    # The old circle's first step: the planner registry importing the learning layer.
    module = "dynabarn.planners.registry"
    text = MODULES[module].read_text() + "\n\ndef _late():\n    from dynabarn.learn.env import DynaBARNEnv\n"
    up = [i for i in _imports_in(text, module) if _layer_of(i) > _layer_of(module)]
    assert up == ["dynabarn.learn.env"]


def test_files_and_functions_stay_readable():
    """No module over 400 lines; no function over 80 without its reason written above it
    (a comment starting "Over 80 lines on purpose")."""
    for module, path in MODULES.items():
        lines = path.read_text().splitlines()
        assert len(lines) <= 400, f"{module}: {len(lines)} lines; split it"
        for node in ast.walk(ast.parse("\n".join(lines))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.end_lineno - node.lineno >= 80:
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                above = "\n".join(lines[max(0, first - 4) : first - 1])
                assert "Over 80 lines on purpose" in above, (
                    f"{module}.{node.name}: {node.end_lineno - node.lineno + 1} lines"
                )


OTHER_LIBRARIES_PRIVATES = {
    "_exit": "os._exit: the documented way to end a forked child without cleanup",
    "_actions": "argparse keeps a parser's options only there (cli/bench.py reads which were given)",
    "_foreach_lerp_": "PyTorch's fused in-place lerp over a list of tensors (TD3's target update)",
    "_request": "imageio's ffmpeg plugin: the only handle on the writer's process",
}
"""Private names of other libraries read on purpose, each with its reason."""


def _private_reads(path: Path) -> list[str]:
    """`x._name` read where x is not self, cls or super() and no `_name` is defined in the
    same module (an attribute set on self, a function, a class attribute), and any
    `from dynabarn... import _name`: one object reaching into another's privates."""
    tree = ast.parse(path.read_text())
    defined = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            defined.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            defined.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            defined.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self":
            defined.add(node.attr)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            owner = node.value
            if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
                continue
            if isinstance(owner, ast.Call) and isinstance(owner.func, ast.Name) and owner.func.id == "super":
                continue
            if node.attr in defined or node.attr in OTHER_LIBRARIES_PRIVATES:
                continue
            found.append(f"{path.name}:{node.lineno}: {ast.unparse(node)}")
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("dynabarn"):
            found += [
                f"{path.name}:{node.lineno}: from {node.module} import {a.name}"
                for a in node.names
                if a.name.startswith("_") and not a.name.startswith("__")
            ]
    return found


def test_no_module_reads_another_objects_privates():
    """Batch and single versions share public records (issue 46): a module reads another
    object's `_attributes` only where they are its own (defined in the same module)."""
    found = [line for path in sorted(PACKAGE.rglob("*.py")) for line in _private_reads(path)]
    assert found == [], "\n".join(found)


def test_the_private_read_check_catches_one(tmp_path):
    bad = tmp_path / "reaches_in.py"
    bad.write_text("from dynabarn.cli import _hidden\n\n\ndef f(env):\n    return env._begin()\n")
    assert len(_private_reads(bad)) == 2
