from pathlib import Path

import cv2
import numpy as np
import pytest

from pascal_calib_ros.io.bags import BagError, image_topics, read_images, write_image_bag


@pytest.fixture()
def images(tmp_path: Path) -> list[Path]:
    out = []
    for k in range(3):
        p = tmp_path / f"img_{k}.png"
        cv2.imwrite(str(p), np.full((12, 16), 40 * k, np.uint8))
        out.append(p)
    return out


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
@pytest.mark.parametrize("compressed", [False, True])
def test_write_then_read(tmp_path: Path, images: list[Path], storage: str, compressed: bool) -> None:
    bag = write_image_bag(tmp_path / "bag", images, "/cam/image", storage, compressed, rate=4.0)
    assert image_topics(bag) == {"/cam/image": "sensor_msgs/msg/CompressedImage" if compressed
                                 else "sensor_msgs/msg/Image"}
    items = list(read_images(bag))
    assert len(items) == 3
    assert items[1].timestamp_ns - items[0].timestamp_ns == 250_000_000
    if compressed:
        assert items[2].fields["format"] == "png"
        img = cv2.imdecode(np.frombuffer(items[2].fields["data"], np.uint8), cv2.IMREAD_GRAYSCALE)
    else:
        f = items[2].fields
        assert f["encoding"] == "mono8" and f["step"] == 16
        img = np.frombuffer(f["data"], np.uint8).reshape(12, 16)
    assert np.all(img == 80)


def test_bad_bags(tmp_path: Path, images: list[Path]) -> None:
    with pytest.raises(BagError, match="not found"):
        list(read_images(tmp_path / "nope"))
    bag = write_image_bag(tmp_path / "bag", images, "/a", "sqlite3")
    with pytest.raises(BagError, match="no image topic '/b'"):
        list(read_images(bag, "/b"))
    with pytest.raises(BagError, match="exists"):
        write_image_bag(bag, images)
    db = next(bag.glob("*.db3"))
    db.write_bytes(db.read_bytes()[:200])  # truncated
    with pytest.raises(BagError):
        list(read_images(bag))
    garbage = tmp_path / "garbage"
    garbage.mkdir()
    (garbage / "metadata.yaml").write_text("not: a bag\n")
    with pytest.raises(BagError):
        list(read_images(garbage))
