"""mrcal from the project's Python: runs ``tools/mrcal_judge.py`` in ``.venv-mrcal`` (Python 3.12/3.13,
made by ``tools/mrcal_venv`` / ``make mrcal-venv``) and returns plain dicts and numpy arrays.

Importable from the project's 3.11 venv (tests, benchmarks): ``sys.path.insert(0, "tools")`` then
``import mrcal_bridge``. Nothing here imports mrcal.

- :func:`available` -> (True, "") or (False, why): whether the judge can run here.
- :func:`calibrate` / :func:`uncertainty` / :func:`model`: one call per judge mode (see
  ``mrcal_judge.py`` for what each computes).

Intrinsics travel as ``{"fx", "fy", "cx", "cy", "D"}``, D in ROS order (plumb_bob = mrcal's
LENSMODEL_OPENCV5, rational_polynomial = LENSMODEL_OPENCV8, the same coefficients in the same order).
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
JUDGE = ROOT / "tools" / "mrcal_judge.py"
LENSMODEL_OF_ROS = {"plumb_bob": "LENSMODEL_OPENCV5", "rational_polynomial": "LENSMODEL_OPENCV8"}
TIMEOUT = 600.0  # s for one judge call


class JudgeError(RuntimeError):
    """The judge refused the request or mrcal failed; the message is the judge's."""


def venv_python() -> Path:
    """The judge's Python: $PASCAL_MRCAL_PYTHON, else .venv-mrcal/bin/python at the repository root."""
    env = os.environ.get("PASCAL_MRCAL_PYTHON")
    return Path(env) if env else ROOT / ".venv-mrcal" / "bin" / "python"


def _env() -> dict[str, str]:
    """This environment without what would make the 3.12 Python load the 3.11 venv's packages."""
    env = dict(os.environ)
    for k in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "PYTHONSTARTUP"):
        env.pop(k, None)
    return env


@functools.cache
def available() -> tuple[bool, str]:
    """(True, "") when the judge's Python runs and imports mrcal; else (False, the reason and the fix)."""
    py = venv_python()
    if not py.exists():
        return False, (f"no mrcal judge: {py} does not exist; run `make mrcal-venv` (needs Python 3.12 or 3.13 "
                       "and PyPI)")
    try:
        r = subprocess.run([str(py), "-c", "import mrcal"], capture_output=True, text=True, timeout=120, env=_env())
    except (OSError, subprocess.TimeoutExpired) as exc:
        return False, f"no mrcal judge: {py} does not run ({exc})"
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["?"])[-1]
        return False, f"no mrcal judge: {py} cannot import mrcal ({last}); run `make mrcal-venv`"
    return True, ""


def run(request: dict[str, Any]) -> dict[str, Any]:
    """One judge call: the request as JSON in, the answer as a dict out (JudgeError on failure)."""
    ok, why = available()
    if not ok:
        raise JudgeError(why)
    r = subprocess.run([str(venv_python()), str(JUDGE), "-"], input=json.dumps(_plain(request)), capture_output=True,
                       text=True, timeout=TIMEOUT, env=_env())
    try:
        ans = json.loads(r.stdout.strip().splitlines()[-1]) if r.stdout.strip() else {}
    except json.JSONDecodeError:
        ans = {}
    if r.returncode != 0 or "error" in ans or not ans:
        raise JudgeError(ans.get("error") or f"mrcal judge exited {r.returncode}: {r.stderr.strip()[-2000:]}")
    ans["log"] = r.stderr
    return ans


def _plain(x: Any) -> Any:
    """numpy arrays and scalars -> lists and floats (NaN kept: JSON's NaN, which both ends read)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, Path):
        return str(x)
    return x


def intrinsics_of(K: np.ndarray, D: Sequence[float]) -> dict[str, Any]:
    """{"fx", "fy", "cx", "cy", "D"} from a 3x3 K and ROS-order D."""
    return {"fx": float(K[0, 0]), "fy": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2]),
            "D": [float(d) for d in np.asarray(D, float).ravel()]}


def K_of(intr: dict[str, Any]) -> np.ndarray:
    """3x3 K of an intrinsics dict."""
    return np.array([[intr["fx"], 0.0, intr["cx"]], [0.0, intr["fy"], intr["cy"]], [0.0, 0.0, 1.0]])


def _arrays(ans: dict[str, Any]) -> dict[str, Any]:
    for k in ("sigma_at_distance", "sigma_at_infinity", "outliers_per_view", "rt_ref_frame", "projected",
              "unprojected", "calobject_warp"):
        if ans.get(k) is not None:
            ans[k] = np.asarray(ans[k], float if k != "outliers_per_view" else int)
    return ans


def _solve(mode: str, observations: Sequence[np.ndarray], object_points: np.ndarray, image_size: tuple[int, int],
           distortion: str, options: dict[str, Any]) -> dict[str, Any]:
    if distortion not in LENSMODEL_OF_ROS:
        raise ValueError(f"mrcal judges {', '.join(LENSMODEL_OF_ROS)}, not {distortion!r}")
    req = {"mode": mode, "observations": [np.asarray(o, float).reshape(-1, 2) for o in observations],
           "object_points": np.asarray(object_points, float).reshape(-1, 3), "image_size": list(image_size),
           "lensmodel": LENSMODEL_OF_ROS[distortion],
           **{k: v for k, v in options.items() if v is not None}}
    return _arrays(run(req))


def calibrate(observations: Sequence[np.ndarray], object_points: np.ndarray, image_size: tuple[int, int], *,
              distortion: str = "plumb_bob", focal: float | None = None, seed: dict[str, Any] | None = None,
              grid: np.ndarray | None = None, distance: float | None = None, noise: float | None = None,
              outlier_rejection: bool = True, regularization: bool = True, board_warp: bool = True,
              model_path: str | Path | None = None) -> dict[str, Any]:
    """mrcal-calibrate-cameras on chessboard corners (mrcal_judge.py's ``calibrate``).

    observations: per view (N, 2) pixels, NaN for a missing corner; object_points (N, 3) metres, a
    planar regular grid; focal (px) or seed intrinsics to start from; grid (M, 2) pixels where the
    projection sigma is wanted, at ``distance`` metres (None: the median camera-to-board-centre
    distance) and at infinity. Returns intrinsics, std, rms_px (per corner, as OpenCV), rms_mrcal
    (mrcal's, per coordinate), noise_px, outliers_per_view, n_outliers, sigma_at_distance (M,),
    sigma_at_infinity (M,), distance_m, calobject_warp, seconds_solve."""
    return _solve("calibrate", observations, object_points, image_size, distortion,
                  dict(focal=focal, seed=seed, grid=grid, distance=distance, noise=noise,
                       outlier_rejection=outlier_rejection, regularization=regularization, board_warp=board_warp,
                       model_path=model_path))


def uncertainty(observations: Sequence[np.ndarray], object_points: np.ndarray, image_size: tuple[int, int], *,
                grid: np.ndarray, distance: float, noise: float | None, distortion: str = "plumb_bob",
                focal: float | None = None, seed: dict[str, Any] | None = None) -> dict[str, Any]:
    """mrcal's projection uncertainty of a least-squares solve of these observations as they are
    (no outlier rejection, no regularisation, a flat board) with observation noise ``noise`` px per
    coordinate (None: mrcal's estimate from the residuals); keys as :func:`calibrate`."""
    return _solve("uncertainty", observations, object_points, image_size, distortion,
                  dict(focal=focal, seed=seed, grid=grid, distance=distance, noise=noise))


def model(*, read: str | Path | None = None, write: str | Path | None = None, K: np.ndarray | None = None,
          D: Sequence[float] | None = None, distortion: str = "plumb_bob", image_size: tuple[int, int] | None = None,
          project: np.ndarray | None = None, unproject: np.ndarray | None = None) -> dict[str, Any]:
    """Read (``read``) or write (``write`` from K, D, distortion, image_size) a .cameramodel, and
    project (N, 3) camera-frame points / unproject (N, 2) pixels to unit rays with it. Returns
    lensmodel, intrinsics, image_size, projected (N, 2), unprojected (N, 3)."""
    req: dict[str, Any] = {"mode": "model", "project": project, "unproject": unproject}
    if write is not None:
        if K is None or D is None or image_size is None:
            raise ValueError("writing a .cameramodel needs K, D and image_size")
        if distortion not in LENSMODEL_OF_ROS:
            raise ValueError(f"mrcal has no model for {distortion!r}; it has {', '.join(LENSMODEL_OF_ROS)}")
        req.update(write=write, intrinsics=intrinsics_of(K, D), image_size=list(image_size),
                   lensmodel=LENSMODEL_OF_ROS[distortion])
    elif read is not None:
        req["read"] = read
    else:
        raise ValueError("model() needs read= or write=")
    return _arrays(run({k: v for k, v in req.items() if v is not None}))
