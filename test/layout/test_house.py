"""The house in figures (issue 23): no import cycle (``TYPE_CHECKING`` imports included), no module
over 500 lines (studies aside), no function over 80 lines, no call with more than 8 positional
arguments. The layer order and rclpy only in ros/ are checked by import-linter in ``make lint`` (pyproject.toml)."""

from __future__ import annotations

import ast
from pathlib import Path

import grimp

PACKAGE = Path(__file__).resolve().parents[2] / "pascal_calib_ros"
MAX_MODULE_LINES, MAX_FUNCTION_LINES, MAX_POSITIONAL = 500, 80, 8


def _modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_no_import_cycle() -> None:
    """No cycle, those through imports made only for annotations (``if TYPE_CHECKING:``) included
    (issue 35): a part of a node types the node it is given as a protocol of what it uses
    (:mod:`pascal_calib_ros.ros.node_parts`), never by importing the node's module."""
    g = grimp.build_graph("pascal_calib_ros", exclude_type_checking_imports=False)
    cycles = [(a, b) for a in g.modules for b in g.find_modules_directly_imported_by(a)
              if a != b and g.chain_exists(importer=b, imported=a)]
    assert not cycles, f"import cycles: {sorted(cycles)[:10]}"


def test_modules_are_small() -> None:
    big = {str(p.relative_to(PACKAGE)): n for p in _modules() if "studies" not in p.parts
           and (n := p.read_text().count("\n") + 1) > MAX_MODULE_LINES}
    assert not big, f"modules over {MAX_MODULE_LINES} lines: {big}"


def test_functions_are_short_and_calls_name_their_arguments() -> None:
    long_functions, wide_calls = [], []
    for p in _modules():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and \
                    node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES:  # type: ignore[operator]
                long_functions.append(f"{p.relative_to(PACKAGE)}:{node.lineno} {node.name}")
            if isinstance(node, ast.Call) and len(node.args) > MAX_POSITIONAL:
                wide_calls.append(f"{p.relative_to(PACKAGE)}:{node.lineno} {ast.unparse(node.func)}")
    assert not long_functions, f"functions over {MAX_FUNCTION_LINES} lines: {long_functions}"
    assert not wide_calls, f"calls with more than {MAX_POSITIONAL} positional arguments: {wide_calls}"


def test_no_private_name_is_imported_across_modules() -> None:
    """A ``_name`` is its module's own (issue 35): another module that needs it gets a public name."""
    found = []
    for p in _modules():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or node.level):
                found += [f"{p.relative_to(PACKAGE)}: {a.name}" for a in node.names
                          if a.name.startswith("_") and not a.name.startswith("__")]
    assert not found, f"private names imported across modules: {found}"


def test_a_subpackage_is_imported_through_its_root() -> None:
    """From outside a subpackage only its root (a folder with ``__init__.py``) is imported, so its
    ``__all__`` is its contract (issue 35; rosbags, scikit-image do the same): ``from ..calibrate
    import calibrate``, never ``from ..calibrate.pipeline import calibrate``. Inside a subpackage its
    modules import each other directly."""
    found = []
    for p in _modules():
        here = p.relative_to(PACKAGE).parts[:-1]
        for node in ast.walk(ast.parse(p.read_text())):
            if not (isinstance(node, ast.ImportFrom) and node.level and node.module) or node.level - 1 > len(here):
                continue
            target = [*here[:len(here) - (node.level - 1)], *node.module.split(".")]
            if target[:1] == list(here[:1]) or not (PACKAGE / target[0] / "__init__.py").exists():
                continue  # the same subpackage, or a top-level module (errors, targets, modes)
            if not (PACKAGE.joinpath(*target) / "__init__.py").exists():
                found.append(f"{p.relative_to(PACKAGE)}:{node.lineno} from {'.'.join(target)}")
    assert not found, f"{len(found)} imports of a subpackage's module from outside it: {found[:10]}"


def test_a_root_exports_what_it_imports() -> None:
    """Every name a subpackage root imports is in its ``__all__`` (what its users may rely on)."""
    missing = []
    for init in PACKAGE.glob("*/**/__init__.py"):  # the package's own root is lazy (its _API table)
        tree = ast.parse(init.read_text())
        names = {a.asname or a.name for n in tree.body if isinstance(n, ast.ImportFrom) for a in n.names}
        exported = set()
        for n in tree.body:
            if isinstance(n, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets):
                exported = set(ast.literal_eval(n.value))
        missing += [f"{init.relative_to(PACKAGE)}: {name}" for name in sorted(names - exported)]
    assert not missing, f"imported by a root but not in its __all__: {missing}"
