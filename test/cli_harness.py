"""Running the installed ``pascal-calib`` command as a user does (shared by the CLI tests)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    exe = shutil.which("pascal-calib", path=str(Path(sys.executable).parent)) or "pascal-calib"
    return subprocess.run([exe, *args], capture_output=True, text=True, cwd=cwd, timeout=600,
                          env={**os.environ, "PYTHONWARNINGS": "ignore"})
