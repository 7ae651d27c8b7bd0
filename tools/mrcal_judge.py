#!/usr/bin/env python3
"""mrcal as a judge: chessboard calibration, projection uncertainty and .cameramodel files.

Runs under ``.venv-mrcal/bin/python`` (mrcal has wheels for Python 3.12/3.13 only; made by
``tools/mrcal_venv``); the project's 3.11 code calls it through ``tools/mrcal_bridge.py``.
Reads one JSON request (a file argument, or standard input), writes one JSON answer to standard
output; anything mrcal prints goes to standard error. A bad request answers ``{"error": ...}``
with exit code 2. NaN travels as JSON's ``NaN`` (Python's json reads and writes it).

Modes (``"mode"``):

- ``calibrate``: what ``mrcal-calibrate-cameras`` does with one camera and a corners cache of
  level-0 corners: seed (``mrcal.seed_stereographic`` from a focal estimate, then a geometry-only
  and a core-only LENSMODEL_STEREOGRAPHIC solve; or, from seed intrinsics, mrcal's monocular
  pose estimates as with ``--seed``), a solve of everything but the board warp, then the final
  solve with the board warp (``calobject_warp``), both with mrcal's outlier rejection and
  regularisation. Observation weights are 1 (a corners cache's level 0), a missing corner has
  weight -1. The noise is mrcal's own estimate from the inlier residuals
  (``_observed_pixel_uncertainty_from_inputs``) unless ``noise`` is given.
- ``uncertainty``: the same solve of a fixed set of observations without outlier rejection,
  regularisation or board warp (each can be turned back on), usually with a given ``noise``: to
  compare the propagation of uncertainty alone.
- ``model``: read (``read``) or write (``write``, from ``intrinsics``) a ``.cameramodel`` and
  project (``project``: (N, 3) camera-frame points) / unproject (``unproject``: (N, 2) pixels ->
  unit rays) with it.

Intrinsics travel as ``{"fx", "fy", "cx", "cy", "D"}`` with D in ROS order: plumb_bob's
(k1, k2, p1, p2, k3) is mrcal's LENSMODEL_OPENCV5 order, rational_polynomial's
(k1, k2, p1, p2, k3, k4, k5, k6) LENSMODEL_OPENCV8's: the same numbers in the same order.

Projection uncertainty (``grid``: (M, 2) pixels): as the project's
``analysis/statistics/uncertainty.projection_uncertainty`` defines it, the point at ``distance`` metres along
the pixel's unit ray (range, not depth: ``mrcal.unproject(..., normalize=True) * distance``), its
2x2 covariance by ``mrcal.projection_uncertainty`` (method ``mean-pcam``: the point carried through
every frame's pose and averaged), worst direction sqrt(lambda_max) ('worstdirection-stdev'); and
the same with ``atinfinity=True``. Without ``distance``: the median distance from the camera to
the observed board's centre.
"""

from __future__ import annotations

import io
import json
import sys
import time
from typing import Any

import numpy as np

LENSMODELS = {"LENSMODEL_OPENCV5": 5, "LENSMODEL_OPENCV8": 8}
ROS_OF_LENSMODEL = {"LENSMODEL_OPENCV5": "plumb_bob", "LENSMODEL_OPENCV8": "rational_polynomial"}
GRID_TOL = 1e-6  # m: how far an object point may sit from the regular grid


class RequestError(ValueError):
    """The request cannot be served; the message says why."""


# -- the board ------------------------------------------------------------------------------------
def board_grid(obj: np.ndarray) -> tuple[int, int, float, np.ndarray, np.ndarray]:
    """Object points (N, 3) of a planar chessboard -> (width_n, height_n, spacing, row (N,), col (N,)).

    mrcal's board is the regular grid (col * spacing, row * spacing, 0), rows along y; the points
    keep their orientation (only shifted so that the smallest x and y are the grid's origin)."""
    obj = np.asarray(obj, float)
    if obj.ndim != 2 or obj.shape[1] != 3 or len(obj) < 4:
        raise RequestError(f"object_points must be (N, 3) with N >= 4, got shape {obj.shape}")
    if np.max(np.abs(obj[:, 2])) > GRID_TOL:
        raise RequestError("object_points must lie in the plane z = 0 (mrcal's chessboard is planar)")
    xs, ys = np.unique(np.round(obj[:, 0], 9)), np.unique(np.round(obj[:, 1], 9))
    steps = np.concatenate([np.diff(xs), np.diff(ys)])
    if not len(steps):
        raise RequestError("object_points must span a grid of at least 2 x 2")
    spacing = float(np.median(steps))
    col = np.rint((obj[:, 0] - xs[0]) / spacing).astype(int)
    row = np.rint((obj[:, 1] - ys[0]) / spacing).astype(int)
    grid = np.stack([xs[0] + col * spacing, ys[0] + row * spacing], 1)
    if np.max(np.abs(grid - obj[:, :2])) > GRID_TOL or spacing <= 0:
        raise RequestError("object_points are not a regular square grid (mrcal needs one spacing along x and y)")
    width_n, height_n = int(col.max()) + 1, int(row.max()) + 1
    if len({(r, c) for r, c in zip(row, col, strict=True)}) != len(obj) or width_n * height_n != len(obj):
        raise RequestError("object_points must be every corner of a width x height grid, each once")
    return width_n, height_n, spacing, row, col


def board_observations(views: list[Any], obj: np.ndarray) -> tuple[np.ndarray, float, int, int]:
    """Per view (N, 2) pixels (NaN: missing) -> mrcal's observations_board (V, H, W, 3) with
    weight 1 for a corner and -1 for a missing one; the spacing and the grid's width and height."""
    width_n, height_n, spacing, row, col = board_grid(obj)
    out = np.zeros((len(views), height_n, width_n, 3))
    for v, q in enumerate(views):
        q = np.asarray(q, float)
        if q.shape != (len(obj), 2):
            raise RequestError(f"view {v}: observations must be ({len(obj)}, 2) like object_points, got {q.shape}")
        ok = np.all(np.isfinite(q), 1)
        out[v, row, col, :2] = np.where(ok[:, None], q, 0.0)
        out[v, row, col, 2] = np.where(ok, 1.0, -1.0)
    return out, spacing, width_n, height_n


# -- solving ---------------------------------------------------------------------------------------
def _lensmodel(req: dict[str, Any]) -> str:
    lensmodel = req.get("lensmodel", "LENSMODEL_OPENCV5")
    if lensmodel not in LENSMODELS:
        raise RequestError(f"lensmodel {lensmodel!r} is not served; choose one of {', '.join(LENSMODELS)}")
    return lensmodel


def intrinsics_vector(intr: dict[str, Any], lensmodel: str) -> np.ndarray:
    """{"fx", "fy", "cx", "cy", "D"} (ROS order) -> mrcal's intrinsics vector; a shorter D is padded
    with zeros (a plumb_bob seed for an OPENCV8 solve)."""
    d = np.asarray(intr.get("D", []), float).ravel()
    n = LENSMODELS[lensmodel]
    if len(d) > n:
        raise RequestError(f"{len(d)} distortion coefficients for {lensmodel}, which has {n}")
    return np.concatenate([[intr["fx"], intr["fy"], intr["cx"], intr["cy"]], d, np.zeros(n - len(d))])


def intrinsics_dict(v: np.ndarray) -> dict[str, Any]:
    return {"fx": float(v[0]), "fy": float(v[1]), "cx": float(v[2]), "cy": float(v[3]), "D": [float(x) for x in v[4:]]}


def _seed(req: dict[str, Any], obs: np.ndarray, spacing: float, width_n: int, height_n: int,
          imagersize: np.ndarray, lensmodel: str) -> tuple[np.ndarray, np.ndarray]:
    """(intrinsics (1, N), rt_ref_frame (V, 6)): mrcal-calibrate-cameras' seeding (module docstring)."""
    import mrcal

    nv = len(obs)
    ifc = np.stack([np.arange(nv), np.zeros(nv, int)], 1).astype(np.int32)
    if req.get("seed"):
        seed = mrcal.cameramodel(intrinsics=(lensmodel, intrinsics_vector(req["seed"], lensmodel)),
                                 imagersize=imagersize)
        Rt_cf = mrcal.estimate_monocular_calobject_poses_Rt_tocam(ifc, obs, spacing, [seed])
        rt_ref_frame = mrcal.estimate_joint_frame_poses(Rt_cf, np.zeros((0, 4, 3)), ifc, width_n, height_n, spacing)
        return intrinsics_vector(req["seed"], lensmodel)[None, :].copy(), rt_ref_frame
    if not req.get("focal"):
        raise RequestError("give a focal estimate (px) or seed intrinsics: mrcal needs one to start")
    intr, _, rt_ref_frame = mrcal.seed_stereographic(imagersizes=imagersize[None, :],
                                                     focal_estimate=float(req["focal"]), indices_frame_camera=ifc,
                                                     observations=obs, object_spacing=spacing)
    common = dict(rt_cam_ref=np.zeros((0, 6)), rt_ref_frame=rt_ref_frame, observations_board=obs,
                  indices_frame_camintrinsics_camextrinsics=np.c_[ifc, -np.ones(nv, int)].astype(np.int32),
                  lensmodel="LENSMODEL_STEREOGRAPHIC", imagersizes=imagersize[None, :],
                  do_optimize_intrinsics_distortions=False, do_optimize_calobject_warp=False,
                  calibration_object_spacing=spacing, do_apply_outlier_rejection=False,
                  do_apply_regularization=False, verbose=False)
    mrcal.optimize(intrinsics=intr, do_optimize_intrinsics_core=False, **common)  # geometry only
    mrcal.optimize(intrinsics=intr, do_optimize_intrinsics_core=True, **common)  # and the core
    # as mrcal-calibrate-cameras' expand_intrinsics: new distortions uniform in +-1e-6, the rational
    # ones 1000x smaller (a fixed random seed here, so that the judge is repeatable)
    new = (np.random.default_rng(0).random((1, LENSMODELS[lensmodel])) - 0.5) * 2e-6
    new[:, 5:8] *= 1e-3
    return np.concatenate([intr, new], 1), rt_ref_frame


def solve(req: dict[str, Any], defaults: dict[str, bool]) -> tuple[dict[str, Any], dict[str, Any], np.ndarray]:
    """Seed and solve (module docstring): (optimization_inputs, final stats, missing mask (V, H, W))."""
    import mrcal

    lensmodel = _lensmodel(req)
    opt = {k: bool(req.get(k, v)) for k, v in defaults.items()}
    views = req.get("observations") or []
    if len(views) < 3:
        raise RequestError(f"{len(views)} views; mrcal needs at least 3")
    obs, spacing, width_n, height_n = board_observations(views, np.asarray(req["object_points"], float))
    missing = obs[..., 2] < 0
    imagersize = np.asarray(req["image_size"], dtype=np.int32)
    intr, rt_ref_frame = _seed(req, obs, spacing, width_n, height_n, imagersize, lensmodel)
    nv = len(obs)
    oi: dict[str, Any] = dict(
        intrinsics=intr, rt_cam_ref=np.zeros((0, 6)), rt_ref_frame=rt_ref_frame, points=None,
        observations_board=obs,
        indices_frame_camintrinsics_camextrinsics=np.c_[np.arange(nv), np.zeros(nv), -np.ones(nv)].astype(np.int32),
        observations_point=None, indices_point_camintrinsics_camextrinsics=None, lensmodel=lensmodel,
        imagersizes=imagersize[None, :], calobject_warp=None, do_optimize_intrinsics_core=True,
        do_optimize_intrinsics_distortions=True, do_optimize_extrinsics=True, do_optimize_frames=True,
        do_optimize_calobject_warp=False, calibration_object_spacing=spacing,
        do_apply_outlier_rejection=opt["outlier_rejection"], do_apply_regularization=opt["regularization"],
        verbose=False)
    stats = mrcal.optimize(**oi)
    if opt["board_warp"]:
        oi["calobject_warp"] = np.zeros(2)
        oi["do_optimize_calobject_warp"] = True
        stats = mrcal.optimize(**oi)
    return oi, stats, missing


def noise_of(oi: dict[str, Any], stats: dict[str, Any], req: dict[str, Any]) -> float:
    """The observation noise (px per coordinate): the request's, or mrcal's estimate."""
    import mrcal

    if req.get("noise") is not None:
        return float(req["noise"])
    return float(mrcal.model_analysis._observed_pixel_uncertainty_from_inputs(oi, x=stats["x"]))


def intrinsics_std(oi: dict[str, Any], noise: float) -> dict[str, Any]:
    """Standard deviations of fx fy cx cy and D from mrcal's propagation of the noise."""
    import mrcal

    i0 = mrcal.state_index_intrinsics(0, **oi)
    n = oi["intrinsics"].shape[-1]
    dF = np.zeros((n, mrcal.num_states(**oi)))
    dF[np.arange(n), i0 + np.arange(n)] = 1.0
    cov = mrcal.model_analysis._propagate_calibration_uncertainty("covariance", dF_dbunpacked=dF,
                                                                  optimization_inputs=oi,
                                                                  observed_pixel_uncertainty=noise)
    return intrinsics_dict(np.sqrt(np.maximum(np.diag(np.atleast_2d(cov)), 0.0)))


def board_distance(oi: dict[str, Any]) -> float:
    """Median distance (m) from the camera to the centre of the board over the views."""
    import mrcal

    obs = oi["observations_board"]
    h, w = obs.shape[1:3]
    s = oi["calibration_object_spacing"]
    centre = np.array([(w - 1) * s / 2, (h - 1) * s / 2, 0.0])
    p = mrcal.transform_point_rt(oi["rt_ref_frame"], centre)
    return float(np.median(np.linalg.norm(p, axis=-1)))


def projection_sigma(oi: dict[str, Any], grid: np.ndarray, distance: float, noise: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Worst-direction projection sigma (px) on the grid at ``distance`` and at infinity."""
    import mrcal

    model = mrcal.cameramodel(optimization_inputs=oi, icam_intrinsics=0)
    rays = mrcal.unproject(np.ascontiguousarray(grid, float), *model.intrinsics(), normalize=True)
    out = []
    for inf in (False, True):
        s = mrcal.projection_uncertainty(rays * distance, model, atinfinity=inf, what="worstdirection-stdev",
                                         observed_pixel_uncertainty=noise)
        out.append(np.where(np.all(np.isfinite(rays), -1), s, np.nan))
    return out[0], out[1]


def solve_answer(req: dict[str, Any], defaults: dict[str, bool]) -> dict[str, Any]:
    """Solve and describe the solution (module docstring)."""
    import mrcal

    t0 = time.perf_counter()
    oi, stats, missing = solve(req, defaults)
    t_solve = time.perf_counter() - t0
    weights = oi["observations_board"][..., 2]
    outliers = np.sum((weights <= 0) & ~missing, axis=(1, 2))
    r = mrcal.measurements_board(oi, x=stats["x"]).reshape(-1, 2)  # inliers only, weight 1
    noise = noise_of(oi, stats, req)
    ans: dict[str, Any] = {
        "lensmodel": oi["lensmodel"], "distortion_model": ROS_OF_LENSMODEL[oi["lensmodel"]],
        "intrinsics": intrinsics_dict(oi["intrinsics"][0]), "std": intrinsics_std(oi, noise),
        "rms_px": float(np.sqrt(np.mean(np.sum(r * r, 1)))) if len(r) else float("nan"),
        "rms_mrcal": float(stats["rms_reproj_error__pixels"]), "worst_px": float(np.sqrt(np.max(np.sum(r * r, 1)))),
        "noise_px": noise, "noise_estimated": req.get("noise") is None,
        "outliers_per_view": [int(k) for k in outliers], "n_outliers": int(np.sum(outliers)),
        "n_points": int(np.sum(~missing)), "calobject_warp": None if oi["calobject_warp"] is None
        else [float(x) for x in oi["calobject_warp"]],
        "rt_ref_frame": oi["rt_ref_frame"].tolist(), "seconds_solve": t_solve,
    }
    if req.get("grid") is not None:
        distance = float(req["distance"]) if req.get("distance") is not None else board_distance(oi)
        t1 = time.perf_counter()
        s_d, s_inf = projection_sigma(oi, np.asarray(req["grid"], float).reshape(-1, 2), distance, noise)
        ans.update(distance_m=distance, sigma_at_distance=s_d.tolist(), sigma_at_infinity=s_inf.tolist(),
                   seconds_uncertainty=time.perf_counter() - t1)
    if req.get("model_path"):
        mrcal.cameramodel(optimization_inputs=oi, icam_intrinsics=0).write(req["model_path"])
        ans["model_path"] = req["model_path"]
    return ans


# -- models ----------------------------------------------------------------------------------------
def model_answer(req: dict[str, Any]) -> dict[str, Any]:
    """Read or write a .cameramodel; project / unproject with it."""
    import mrcal

    if req.get("write"):
        lensmodel = _lensmodel(req)
        if "intrinsics" not in req or "image_size" not in req:
            raise RequestError("writing a model needs intrinsics and image_size")
        extr = np.asarray(req.get("rt_cam_ref", np.zeros(6)), float)
        model = mrcal.cameramodel(intrinsics=(lensmodel, intrinsics_vector(req["intrinsics"], lensmodel)),
                                  imagersize=np.asarray(req["image_size"], int), rt_cam_ref=extr)
        model.write(req["write"], note=req.get("note"))
    elif req.get("read"):
        model = mrcal.cameramodel(req["read"])
    else:
        raise RequestError("mode model needs 'read' (a .cameramodel path) or 'write' (a path to write)")
    lensmodel, v = model.intrinsics()
    ans: dict[str, Any] = {"lensmodel": lensmodel, "image_size": [int(x) for x in model.imagersize()],
                           "rt_cam_ref": model.rt_cam_ref().tolist()}
    if lensmodel in LENSMODELS:
        ans["intrinsics"] = intrinsics_dict(v)
        ans["distortion_model"] = ROS_OF_LENSMODEL[lensmodel]
    else:
        ans["intrinsics_vector"] = v.tolist()
    if req.get("project") is not None:
        p = np.asarray(req["project"], float).reshape(-1, 3)
        ans["projected"] = mrcal.project(p, lensmodel, v).tolist()
    if req.get("unproject") is not None:
        q = np.asarray(req["unproject"], float).reshape(-1, 2)
        ans["unprojected"] = mrcal.unproject(q, lensmodel, v, normalize=True).tolist()
    return ans


# -- the command ------------------------------------------------------------------------------------
CALIBRATE = {"outlier_rejection": True, "regularization": True, "board_warp": True}
UNCERTAINTY = {"outlier_rejection": False, "regularization": False, "board_warp": False}


def answer(req: dict[str, Any]) -> dict[str, Any]:
    mode = req.get("mode")
    if mode == "calibrate":
        return solve_answer(req, CALIBRATE)
    if mode == "uncertainty":
        return solve_answer(req, UNCERTAINTY)
    if mode == "model":
        return model_answer(req)
    raise RequestError(f"unknown mode {mode!r}: calibrate, uncertainty or model")


def main(argv: list[str]) -> int:
    text = open(argv[1]).read() if len(argv) > 1 and argv[1] != "-" else sys.stdin.read()
    out = sys.stdout
    sys.stdout = sys.stderr  # whatever mrcal prints must not mix with the answer
    try:
        req = json.loads(text)
        if not isinstance(req, dict):
            raise RequestError("the request must be a JSON object")
        ans, code = answer(req), 0
    except (RequestError, KeyError, json.JSONDecodeError) as exc:
        ans, code = {"error": f"{type(exc).__name__}: {exc}"}, 2
    except Exception as exc:  # mrcal's own failures (a solve that does not converge, a bad model file)
        ans, code = {"error": f"mrcal failed: {type(exc).__name__}: {exc}"}, 1
    finally:
        sys.stdout = out
    buf = io.StringIO()
    json.dump(ans, buf)
    out.write(buf.getvalue() + "\n")
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv))
