"""The launch files (launch/*.launch.py, installed by setup.py): every executable they start is one
setup.py installs, every argument that sets a node parameter names one of that node's parameters
(and the publish file's defaults are the publisher's). Read from their source, as ``ros2 launch`` is not
on PyPI; where the ``launch`` package is installed (a ROS install) each description is also built."""

from __future__ import annotations

import ast
import importlib.util
import re
from pathlib import Path

import pytest

from pascal_calib_ros.ros.params import PARAMS
from pascal_calib_ros.ros.publisher_node import PARAMS as PUBLISHER_PARAMS

ROOT = Path(__file__).resolve().parents[2]
LAUNCH = sorted((ROOT / "launch").glob("*.launch.py"))
# executable -> the names of its parameters
NODE_PARAMS = {"calibration_node": {p.name for p in PARAMS}, "publisher": {n for n, _, _ in PUBLISHER_PARAMS}}


def _installed_executables() -> set[str]:
    return set(re.findall(r'"([\w-]+) = pascal_calib_ros\.[\w.]+:main"', (ROOT / "setup.py").read_text()))


def _literal(tree: ast.Module, name: str) -> dict:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in node.targets):
            value = ast.literal_eval(node.value)
            assert isinstance(value, dict)
            return value
    raise AssertionError(f"no {name} in the launch file")


def _node_calls(tree: ast.Module) -> list[ast.Call]:
    return [n for n in ast.walk(tree)
            if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "Node"]


def _keyword(call: ast.Call, name: str) -> ast.expr | None:
    return next((k.value for k in call.keywords if k.arg == name), None)


def test_the_package_installs_its_launch_files() -> None:
    assert [p.name for p in LAUNCH] == ["calibrate.launch.py", "publish.launch.py"]
    assert '("share/" + package_name + "/launch", glob("launch/*.launch.py"))' in (ROOT / "setup.py").read_text()


@pytest.mark.parametrize("path", LAUNCH, ids=lambda p: p.name)
def test_launch_file_starts_installed_executables_with_their_own_parameters(path: Path) -> None:
    tree = ast.parse(path.read_text())
    calls = _node_calls(tree)
    assert calls, "no Node in the launch file"
    installed = _installed_executables()
    for call in calls:
        exe = _keyword(call, "executable")
        pkg = _keyword(call, "package")
        assert isinstance(exe, ast.Constant) and exe.value in installed, ast.dump(call)
        assert isinstance(pkg, ast.Constant) and pkg.value == "pascal_calib_ros"
        known = NODE_PARAMS[exe.value]
        arguments = _literal(tree, "ARGUMENTS")
        assert arguments and set(arguments) <= known, set(arguments) - known
        # a dict literal of parameters in the Node call: only the node's parameter names
        params = _keyword(call, "parameters")
        for d in ast.walk(params) if params is not None else ():
            if isinstance(d, ast.Dict):
                keys = {ast.literal_eval(k) for k in d.keys if k is not None}
                assert keys <= known, keys - known


def test_publish_launch_defaults_are_the_publishers() -> None:
    tree = ast.parse((ROOT / "launch" / "publish.launch.py").read_text())
    defaults = _literal(tree, "DEFAULTS")
    assert defaults == {n: str(d) for n, d, _ in PUBLISHER_PARAMS}


def test_calibrate_launch_remaps_the_nodes_image_topics() -> None:
    from pascal_calib_ros.ros.interfaces import CALIBRATION_NODE_INTERFACES, STEREO_NODE_INTERFACES

    remaps = _literal(ast.parse((ROOT / "launch" / "calibrate.launch.py").read_text()), "REMAPS")
    subscribed = {i.name for i in (*CALIBRATION_NODE_INTERFACES, *STEREO_NODE_INTERFACES) if i.kind == "sub"}
    assert set(remaps.values()) <= subscribed, set(remaps.values()) - subscribed


@pytest.mark.parametrize("path", LAUNCH, ids=lambda p: p.name)
def test_launch_description_builds_where_launch_is_installed(path: Path) -> None:
    if importlib.util.find_spec("launch") is None or importlib.util.find_spec("launch_ros") is None:
        pytest.skip("the ROS `launch` / `launch_ros` packages are not installed (not on PyPI): "
                    "only the static checks above ran")
    spec = importlib.util.spec_from_file_location(path.stem.replace(".", "_"), path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    names = {a.name for a in description.get_launch_arguments()}
    assert set(module.ARGUMENTS) <= names
