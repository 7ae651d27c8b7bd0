"""sensor_msgs image conversion without ROS: every encoding, step padding, and bad input."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pascal_calib_ros.io.image_msgs import (
    SUPPORTED_ENCODINGS,
    ImageConversionError,
    compressed_to_grey,
    grey_to_image_fields,
    image_to_grey,
)


def _msg(img: np.ndarray, enc: str, pad: int = 0, big: bool = False) -> SimpleNamespace:
    h, w = img.shape[:2]
    row = img.reshape(h, -1)
    if big:
        row = row.astype(row.dtype.newbyteorder(">"))
    raw = row.view(np.uint8).reshape(h, -1)
    step = raw.shape[1] + pad
    buf = np.zeros((h, step), np.uint8)
    buf[:, : raw.shape[1]] = raw
    return SimpleNamespace(height=h, width=w, encoding=enc, step=step, is_bigendian=int(big), data=buf.tobytes())


@pytest.mark.parametrize("pad", [0, 3, 64])
def test_colour_and_mono_encodings_with_padding(pad: int) -> None:
    rng = np.random.default_rng(0)
    bgr = rng.integers(0, 255, (30, 41, 3), dtype=np.uint8)
    grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    assert np.array_equal(image_to_grey(_msg(bgr, "bgr8", pad)), grey)
    assert np.array_equal(image_to_grey(_msg(bgr[..., ::-1].copy(), "rgb8", pad)), grey)
    bgra = np.dstack([bgr, np.full((30, 41), 255, np.uint8)])
    assert np.array_equal(image_to_grey(_msg(bgra, "bgra8", pad)), grey)
    assert np.array_equal(image_to_grey(_msg(bgra[..., [2, 1, 0, 3]].copy(), "rgba8", pad)), grey)
    assert np.array_equal(image_to_grey(_msg(grey, "mono8", pad)), grey)
    m16 = rng.integers(0, 65535, (30, 41), dtype=np.uint16)
    assert np.array_equal(image_to_grey(_msg(m16, "mono16", pad)), m16)
    assert np.array_equal(image_to_grey(_msg(m16, "mono16", pad, big=True)), m16)


def test_bayer_is_demosaiced() -> None:
    grey = np.tile(np.linspace(20, 220, 64).astype(np.uint8), (48, 1))
    out = image_to_grey(_msg(grey, "bayer_rggb8"))
    assert out.shape == (48, 64) and abs(float(out.mean()) - float(grey.mean())) < 3
    assert {"bayer_bggr8", "bayer_gbrg16", "mono8", "rgba8"} <= set(SUPPORTED_ENCODINGS)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"encoding": "yuv422"}, "unsupported encoding"),
        ({"step": 10}, "step 10 is smaller"),
        ({"data": b"\x00" * 100}, "data has 100 bytes"),
        ({"height": 0}, "empty image"),
        ({"width": 10**6, "height": 10**6, "step": 10**6}, "larger than"),
    ],
)
def test_bad_messages_raise_clear_errors(change: dict, message: str) -> None:
    m = _msg(np.zeros((20, 30), np.uint8), "mono8")
    for k, v in change.items():
        setattr(m, k, v)
    with pytest.raises(ImageConversionError, match=message):
        image_to_grey(m)


def test_compressed_round_trip_and_corruption() -> None:
    img = (np.random.default_rng(1).random((40, 50)) * 255).astype(np.uint8)
    _ok, png = cv2.imencode(".png", img)
    assert np.array_equal(compressed_to_grey(SimpleNamespace(format="png", data=png.tobytes())), img)
    for bad in (b"", png.tobytes()[:40], b"\xff\xd8\xff garbage"):
        with pytest.raises(ImageConversionError):
            compressed_to_grey(SimpleNamespace(format="jpeg", data=bad))


def test_publish_fields() -> None:
    f = grey_to_image_fields(np.zeros((5, 7, 3), np.uint8))
    assert f["encoding"] == "bgr8" and f["step"] == 21 and len(f["data"]) == 105
    with pytest.raises(ImageConversionError):
        grey_to_image_fields(np.zeros((5, 7), np.float32))


@settings(max_examples=300, deadline=None)
@given(height=st.integers(-2, 40), width=st.integers(-2, 40), step=st.integers(-5, 200),
       enc=st.sampled_from([*SUPPORTED_ENCODINGS, "32FC1", "", "MONO8"]), size=st.integers(0, 5000),
       big=st.booleans())
def test_arbitrary_fields_never_crash(height: int, width: int, step: int, enc: str, size: int, big: bool) -> None:
    m = SimpleNamespace(height=height, width=width, step=step, encoding=enc, is_bigendian=int(big),
                        data=bytes(size))
    try:
        out = image_to_grey(m)
    except ImageConversionError:
        return
    assert out.shape == (height, width)
