"""sensor_msgs image conversion without ROS: every encoding, step padding, and bad input."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from encoded_images import YUV422, encode_grey, pack_rows
from hypothesis import given, settings
from hypothesis import strategies as st

from pascal_calib_ros.io.image_msgs import (
    SUPPORTED_ENCODINGS,
    ImageConversionError,
    compressed_to_grey,
    grey_to_image_fields,
    image_to_grey,
    supported_encodings_text,
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


_YUV_TO_GREY = {"uyvy": cv2.COLOR_YUV2GRAY_UYVY, "yuv422": cv2.COLOR_YUV2GRAY_UYVY,
                "yuyv": cv2.COLOR_YUV2GRAY_YUY2, "yuv422_yuy2": cv2.COLOR_YUV2GRAY_YUY2,
                "nv12": cv2.COLOR_YUV2GRAY_NV12, "nv21": cv2.COLOR_YUV2GRAY_NV21}


@pytest.mark.parametrize("pad", [0, 5, 64])
@pytest.mark.parametrize("enc", sorted(_YUV_TO_GREY))
def test_yuv_gives_opencvs_luma(enc: str, pad: int) -> None:
    """Random bytes in the encoding's layout: the grey image is OpenCV's YUV2GRAY of them (the Y
    samples), and a colour image converted by OpenCV to YUV comes back as its luma."""
    rng = np.random.default_rng(3)
    h, w = 30, 42
    raw = rng.integers(0, 256, (h, 2 * w) if enc in YUV422 else (h + h // 2, w), dtype=np.uint8)
    step, data = pack_rows(raw, pad)
    m = SimpleNamespace(height=h, width=w, encoding=enc, step=step, is_bigendian=0, data=data)
    ref = cv2.cvtColor(raw.reshape(h, w, 2) if enc in YUV422 else raw, _YUV_TO_GREY[enc])
    out = image_to_grey(m)
    assert out.dtype == np.uint8 and out.shape == (h, w) and np.array_equal(out, ref)
    if enc in YUV422:  # OpenCV's own BGR -> YUV 4:2:2, then back to BGR: the luma matches
        bgr = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        to_yuv = cv2.COLOR_BGR2YUV_UYVY if YUV422[enc] == 1 else cv2.COLOR_BGR2YUV_YUY2
        packed = cv2.cvtColor(bgr, to_yuv)
        step, data = pack_rows(packed.reshape(h, -1), pad)
        m = SimpleNamespace(height=h, width=w, encoding=enc.upper(), step=step, is_bigendian=0, data=data)
        assert np.array_equal(image_to_grey(m), packed[..., YUV422[enc]])


@pytest.mark.parametrize("big", [False, True])
@pytest.mark.parametrize("enc", ["rgb16", "bgr16", "rgba16", "bgra16"])
def test_16_bit_colour(enc: str, big: bool) -> None:
    """16-bit colour -> 16-bit grey: OpenCV's conversion of the 16-bit pixels, and the 8-bit
    reference scaled by 257 within one 8-bit level."""
    rng = np.random.default_rng(4)
    bgr8 = rng.integers(0, 256, (25, 33, 3), dtype=np.uint8)
    grey8 = cv2.cvtColor(bgr8, cv2.COLOR_BGR2GRAY)
    bgr16 = bgr8.astype(np.uint16) * 257  # the full 8-bit range onto the full 16-bit range
    order = {"rgb16": [2, 1, 0], "bgr16": [0, 1, 2], "rgba16": [2, 1, 0], "bgra16": [0, 1, 2]}[enc]
    arr = bgr16[..., order]
    if enc.endswith("a16"):
        arr = np.dstack([arr, rng.integers(0, 65536, (25, 33), dtype=np.uint16)])  # alpha: ignored
    m = _msg(np.ascontiguousarray(arr), enc, pad=6, big=big)
    out = image_to_grey(m)
    assert out.dtype == np.uint16 and out.shape == (25, 33)
    assert np.array_equal(out, cv2.cvtColor(bgr16, cv2.COLOR_BGR2GRAY))
    assert np.abs(out.astype(float) / 257 - grey8).max() <= 0.51  # the 8-bit result rounds


@settings(max_examples=150, deadline=None)
@given(half_h=st.integers(1, 12), half_w=st.integers(1, 15), pad=st.integers(0, 9), big=st.booleans(),
       enc=st.sampled_from([e for e in SUPPORTED_ENCODINGS if not e.startswith("bayer")]), seed=st.integers(0, 99))
def test_every_encoding_carries_a_grey_image(half_h: int, half_w: int, pad: int, big: bool, enc: str,
                                             seed: int) -> None:
    """A grey image written in any encoding (colour: equal channels; YUV: random chroma; 16-bit:
    grey x 257, either byte order; padded rows) comes back exactly."""
    grey = np.random.default_rng(seed).integers(0, 256, (2 * half_h, 2 * half_w), dtype=np.uint8)
    out = image_to_grey(encode_grey(grey, enc, pad, big, seed))
    deep = out.dtype == np.uint16
    assert deep == ("16" in enc)
    assert np.array_equal(out, grey.astype(np.uint16) * 257 if deep else grey)


@pytest.mark.parametrize(
    ("enc", "change", "message"),
    [
        ("yuv422", {"width": 31, "step": 62}, "needs an even width, got 31"),
        ("yuv422_yuy2", {"step": 50}, "step 50 is smaller than the 80 bytes"),
        ("uyvy", {"data": bytes(100)}, "data has 100 bytes"),
        ("nv12", {"height": 19}, "needs an even width and height, got 40x19"),
        ("nv21", {"data": bytes(40 * 20)}, r"data has 800 bytes; 40x20 nv21 with step 40 needs 1200 \(30 rows\)"),
        ("nv12", {"step": 39}, "step 39 is smaller"),
        ("rgb16", {"step": 200}, "step 200 is smaller than the 240 bytes"),
        ("bgra16", {"data": bytes(6399)}, "data has 6399 bytes"),
    ],
)
def test_bad_yuv_and_16_bit_messages(enc: str, change: dict, message: str) -> None:
    m = encode_grey(np.zeros((20, 40), np.uint8), enc)
    for k, v in change.items():
        setattr(m, k, v)
    with pytest.raises(ImageConversionError, match=message):
        image_to_grey(m)


def test_the_list_of_encodings_is_quoted_by_the_error() -> None:
    for enc in ("yuv422", "yuv422_yuy2", "uyvy", "yuyv", "nv12", "nv21", "rgb16", "bgr16", "rgba16", "bgra16"):
        assert enc in SUPPORTED_ENCODINGS
    with pytest.raises(ImageConversionError) as e:
        image_to_grey(SimpleNamespace(height=2, width=2, encoding="32FC1", step=8, is_bigendian=0, data=bytes(16)))
    assert supported_encodings_text() in str(e.value) and "nv12" in str(e.value)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"encoding": "nv24"}, "unsupported encoding"),
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
