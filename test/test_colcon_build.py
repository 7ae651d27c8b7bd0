"""`colcon build` of the package in a fresh workspace (the ament_python layout ROS users get)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
COLCON = Path(sys.executable).parent / "colcon"


@pytest.mark.skipif(not COLCON.exists(), reason="colcon not installed in this environment")
def test_colcon_build_installs_the_executables(tmp_path: Path) -> None:
    src = tmp_path / "src" / "pascal_calib_ros"
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.split()
    for f in files:
        if f.startswith(("demo_out/", "out/")) or not (ROOT / f).is_file():
            continue
        (src / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, src / f)
    env = {**os.environ, "AMENT_PREFIX_PATH": str(Path(sys.executable).parents[1]),
           "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}"}
    r = subprocess.run([str(COLCON), "build", "--event-handlers", "console_direct-"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    prefix = tmp_path / "install" / "pascal_calib_ros"
    for exe in ("calibration_node", "replay_node", "pascal-calib"):
        assert (prefix / "lib" / "pascal_calib_ros" / exe).exists(), exe
    share = prefix / "share" / "pascal_calib_ros"
    assert (share / "package.xml").exists() and (share / "config" / "calibration_node.yaml").exists()
    assert (share / "config" / "targets" / "ring_a4.yaml").exists()
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / "pascal_calib_ros").exists()
