"""`colcon build` of the package in a fresh workspace, as a ROS user builds it, and the installed node
started from there.

The user's Python has the dependencies but not this project (``.venv`` has it installed editable,
which would hide a broken install): the build runs with a throw-away venv that sees this
environment's site-packages as plain path entries, so their ``.pth`` hooks (the editable finder)
never run. The only ``pascal_calib_ros`` that Python can import is the one ``colcon`` installed.
"""

from __future__ import annotations

import os
import shutil
import signal
import site
import subprocess
import sys
import time
import venv
from dataclasses import dataclass
from pathlib import Path

import pytest
from ros_harness import RosClient, next_domain_id, require_netns, status_subscription

pytestmark = pytest.mark.ros  # builds with colcon and starts the installed node

ROOT = Path(__file__).resolve().parents[2]
PKG = "pascal_calib_ros"


@dataclass
class Workspace:
    root: Path
    python: Path  # the user's Python: dependencies, not this project
    env: dict[str, str]  # the environment before `source install/setup.bash`

    @property
    def prefix(self) -> Path:
        return self.root / "install" / PKG

    def sourced(self, *argv: str) -> list[str]:
        """``argv`` run by bash after `source install/setup.bash` (what a ROS user does)."""
        return ["bash", "-c", f'source "{self.root}/install/setup.bash" && exec "$@"', "bash", *argv]


def _python_without_the_project(where: Path) -> Path:
    venv.EnvBuilder(with_pip=False, symlinks=True).create(where)
    site_dir = where / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    (site_dir / "dependencies.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    return where / "bin" / "python"


def _base_env() -> dict[str, str]:
    """This environment (LD_LIBRARY_PATH of the ROS wheels included) without the source tree on
    PYTHONPATH, with this environment as the underlay (AMENT_PREFIX_PATH)."""
    env = dict(os.environ)
    keep = [p for p in env.get("PYTHONPATH", "").split(os.pathsep)
            if p and not Path(p).resolve().is_relative_to(ROOT)]
    env["PYTHONPATH"] = os.pathsep.join(keep)
    if not keep:
        env.pop("PYTHONPATH")
    env.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    return env


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Workspace:
    import importlib.util

    assert importlib.util.find_spec("colcon_core"), "colcon is needed (requirements.txt; package.xml test_depend)"
    root = tmp_path_factory.mktemp("ws")
    src = root / "src" / PKG
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.split()
    for f in files:
        if f.startswith(("demo_out/", "out/")) or not (ROOT / f).is_file():
            continue
        (src / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, src / f)
    ws = Workspace(root, _python_without_the_project(tmp_path_factory.mktemp("user_python")), _base_env())
    r = subprocess.run([str(ws.python), "-c", f"import {PKG}"], cwd=root, env=ws.env, capture_output=True, text=True)
    assert r.returncode != 0, (f"the build Python must not have {PKG} installed (it would hide a broken install); "
                               f"it imports it from elsewhere: {r.stdout}{r.stderr}")
    r = subprocess.run([str(ws.python), "-m", "colcon", "build", "--event-handlers", "console_direct-"], cwd=root,
                       env=ws.env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return ws


def test_colcon_build_installs_the_executables_and_data(workspace: Workspace) -> None:
    prefix = workspace.prefix
    for exe in ("calibration_node", "replay_node", "publisher", "pascal-calib"):
        assert (prefix / "lib" / PKG / exe).exists(), exe
    share = prefix / "share" / PKG
    assert (share / "package.xml").exists() and (share / "config" / "calibration_node.yaml").exists()
    for launch in ("calibrate.launch.py", "publish.launch.py"):  # ros2 launch pascal_calib_ros <launch>
        assert (share / "launch" / launch).is_file(), launch
    # the message packages tools/build_msg_package.py builds for the PyPI venv are not a workspace's packages
    assert not (workspace.root / "install" / "tf2_msgs").exists()
    assert (share / "config" / "targets" / "ring_a4.yaml").exists()
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / PKG).exists()


def test_installed_package_imports_and_finds_its_data_through_the_ament_index(workspace: Workspace,
                                                                               tmp_path: Path) -> None:
    code = (f"import {PKG}, {PKG}.targets as t; print({PKG}.__file__); print(t.packaged_targets_dir()); "
            "print(t.resolve_target('ring_a4').name)")
    r = subprocess.run(workspace.sourced(str(workspace.python), "-c", code), cwd=tmp_path,
                       env=workspace.env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
    module, config, name = r.stdout.splitlines()[-3:]
    assert Path(module).is_relative_to(workspace.prefix / "lib"), module  # not the source tree, not the copy in src/
    assert Path(config) == workspace.prefix / "share" / PKG / "config" / "targets", config
    assert name == "ring_a4"


@require_netns
def test_installed_calibration_node_starts_from_any_directory(workspace: Workspace, tmp_path: Path) -> None:
    """`source install/setup.bash`, start lib/pascal_calib_ros/calibration_node (default target)
    from a directory outside the sources: it comes up and publishes its status; SIGINT stops it
    cleanly (exit 0)."""
    dom = next_domain_id()
    env = {**workspace.env, "ROS_DOMAIN_ID": str(dom), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "PYTHONUNBUFFERED": "1"}
    env.pop("ROS_STATIC_PEERS", None)
    exe = workspace.prefix / "lib" / PKG / "calibration_node"
    assert exe.read_text().startswith(f"#!{workspace.python}\n"), exe.read_text()[:200]
    log = tmp_path / "node.log"
    with open(log, "w") as out:
        proc = subprocess.Popen(workspace.sourced(str(exe)), cwd=tmp_path, env=env, stdout=out,
                                stderr=subprocess.STDOUT)
    client = RosClient(dom)
    try:
        status = status_subscription(client)
        up = client.spin_until(lambda: bool(status) or proc.poll() is not None, 30.0)
        assert up and proc.poll() is None, f"exit code {proc.poll()}:\n{log.read_text()}"
        time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        rc = proc.wait(15.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        client.close()
    text = log.read_text()
    assert rc == 0, f"exit code {rc}:\n{text}"
    assert "Traceback" not in text and "FATAL" not in text, text
