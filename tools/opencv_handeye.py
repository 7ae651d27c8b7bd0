#!/usr/bin/env python3
"""OpenCV 4.x's calibrateHandEye (all five methods) on the poses a study wrote, for comparison.

Runs in a separate Python with OpenCV 4.x (the package pins OpenCV 5.0, which has no
calibrateHandEye), e.g. ``python3.11 -m venv /tmp/cv4 && /tmp/cv4/bin/pip install
opencv-python-headless==4.10.0.84 numpy``; only numpy and cv2 are used.

    /tmp/cv4/bin/python tools/opencv_handeye.py IN.json OUT.json

IN.json: {"mode": "eye_in_hand" | "eye_to_hand", "views": [{"R_base_tool": 3x3, "t_base_tool": 3,
"R_cam_target": 3x3, "t_cam_target": 3}, ...]} (metres). OpenCV's convention: eye in hand, the
gripper-to-base poses give cam2gripper; eye to hand, base-to-gripper poses passed in their place
give cam2base. OUT.json: {"opencv": version, "methods": {name: {"R": 3x3, "t": 3}}} - the
transform mapping camera points into the tool (eye in hand) or base (eye to hand) frame.
"""

import json
import sys

import cv2
import numpy as np

METHODS = {"tsai": "CALIB_HAND_EYE_TSAI", "park": "CALIB_HAND_EYE_PARK", "horaud": "CALIB_HAND_EYE_HORAUD",
           "andreff": "CALIB_HAND_EYE_ANDREFF", "daniilidis": "CALIB_HAND_EYE_DANIILIDIS"}


def main(inp: str, out: str) -> int:
    doc = json.load(open(inp))
    Rg, tg, Rc, tc = [], [], [], []
    for v in doc["views"]:
        R, t = np.array(v["R_base_tool"], float), np.array(v["t_base_tool"], float)
        if doc["mode"] == "eye_to_hand":
            R, t = R.T, -R.T @ t
        Rg.append(R)
        tg.append(t.reshape(3, 1))
        Rc.append(np.array(v["R_cam_target"], float))
        tc.append(np.array(v["t_cam_target"], float).reshape(3, 1))
    res = {}
    for name, flag in METHODS.items():
        try:
            R, t = cv2.calibrateHandEye(Rg, tg, Rc, tc, method=getattr(cv2, flag))
            res[name] = {"R": np.asarray(R).tolist(), "t": np.asarray(t).ravel().tolist()}
        except cv2.error as e:
            res[name] = {"error": str(e).strip().splitlines()[-1]}
    json.dump({"opencv": cv2.__version__, "methods": res}, open(out, "w"), indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
