"""Stereo bags (io/stereo_bags.py): two image topics written from paired files and read back in
recorded order, with the right camera's delay."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from pascal_calib_ros.io.bags import BagError
from pascal_calib_ros.io.stereo_bags import read_image_topics, write_stereo_bag


def _files(folder: Path, values: list[int]) -> list[Path]:
    folder.mkdir()
    out = []
    for k, v in enumerate(values):
        p = folder / f"{k:03d}.png"
        cv2.imwrite(str(p), np.full((8, 10), v, np.uint8))
        out.append(p)
    return out


@pytest.mark.parametrize("compressed", [False, True])
def test_write_then_read_both_topics_in_recorded_order(tmp_path: Path, compressed: bool) -> None:
    left, right = _files(tmp_path / "l", [10, 20, 30]), _files(tmp_path / "r", [11, 21, 31])
    bag = write_stereo_bag(tmp_path / "bag", left, right, storage="mcap", compressed=compressed, rate=5.0,
                           right_delay=0.004)
    items = list(read_image_topics(bag, ("/left/image_raw", "/right/image_raw")))
    assert [side for side, _ in items] == [0, 1, 0, 1, 0, 1]
    stamps = [it.stamp_ns for _, it in items]
    assert stamps[1] - stamps[0] == 4_000_000 and stamps[2] - stamps[0] == 200_000_000
    assert [it.frame_id for _, it in items[:2]] == ["left_camera_optical_frame", "right_camera_optical_frame"]
    f = items[3][1].fields
    img = (cv2.imdecode(np.frombuffer(f["data"], np.uint8), cv2.IMREAD_GRAYSCALE) if compressed
           else np.frombuffer(f["data"], np.uint8).reshape(8, 10))
    assert np.all(img == 21)


def test_bad_stereo_bags(tmp_path: Path) -> None:
    left, right = _files(tmp_path / "l", [1, 2]), _files(tmp_path / "r", [3])
    with pytest.raises(BagError, match="one right image per left image"):
        write_stereo_bag(tmp_path / "a", left, right)
    with pytest.raises(BagError, match="right_delay"):
        write_stereo_bag(tmp_path / "b", left, left, rate=10.0, right_delay=0.2)
    bag = write_stereo_bag(tmp_path / "c", left, left)
    with pytest.raises(BagError, match="no image topic '/cam'"):
        list(read_image_topics(bag, ("/left/image_raw", "/cam")))
