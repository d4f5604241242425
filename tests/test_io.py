"""Tests for dopplertof.io: EXR/NPY/JSON round trips, channel order and error messages."""

from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from dopplertof import io


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def _with_specials(array: np.ndarray) -> np.ndarray:
    """Put NaN, +-inf, -0 and tiny/huge float32 values into the first pixels."""
    flat = array.reshape(-1)
    flat[:6] = [np.nan, np.inf, -np.inf, -0.0, np.finfo(np.float32).tiny, -3.0e38]
    return array


def _assert_bitwise_equal(actual: np.ndarray, expected: np.ndarray) -> None:
    assert actual.dtype == np.float32
    assert actual.shape == expected.shape
    # Compare bit patterns: catches sign-of-zero and NaN loss that == would hide.
    np.testing.assert_array_equal(actual.view(np.uint32), expected.view(np.uint32))


# --------------------------------------------------------------------------------- EXR

def test_exr_single_channel_round_trip_is_exact(tmp_path, rng):
    image = _with_specials(rng.normal(scale=5.0, size=(17, 23)).astype(np.float32))
    path = io.write_exr(tmp_path / "y.exr", image)
    assert path == tmp_path / "y.exr"
    result = io.read_exr(path)
    _assert_bitwise_equal(result, image)
    assert list(io.read_exr_channels(path)) == ["Y"]


def test_exr_rgb_round_trip_is_exact(tmp_path, rng):
    image = _with_specials(rng.normal(size=(9, 14, 3)).astype(np.float32))
    io.write_exr(str(tmp_path / "rgb.exr"), image)  # str path as well as Path
    _assert_bitwise_equal(io.read_exr(tmp_path / "rgb.exr"), image)
    channels = io.read_exr_channels(tmp_path / "rgb.exr")
    assert list(channels) == ["R", "G", "B"]
    for i, name in enumerate("RGB"):
        _assert_bitwise_equal(channels[name], image[:, :, i])


def test_exr_multichannel_keeps_caller_order(tmp_path, rng):
    # Names chosen so that the caller's order is not alphabetical (EXR stores sorted).
    names = ["velocity", "R", "depth.Z", "A2"]
    image = _with_specials(rng.normal(size=(6, 5, 4)).astype(np.float32))
    io.write_exr(tmp_path / "multi.exr", image, channels=names)
    _assert_bitwise_equal(io.read_exr(tmp_path / "multi.exr"), image)
    channels = io.read_exr_channels(tmp_path / "multi.exr")
    assert list(channels) == names
    _assert_bitwise_equal(channels["velocity"], image[:, :, 0])


def test_exr_named_single_channel(tmp_path):
    image = np.arange(12, dtype=np.float32).reshape(3, 4) - 6
    io.write_exr(tmp_path / "z.exr", image, channels=["Z"])
    assert list(io.read_exr_channels(tmp_path / "z.exr")) == ["Z"]
    _assert_bitwise_equal(io.read_exr(tmp_path / "z.exr"), image)


def test_exr_strided_input_is_written_correctly(tmp_path, rng):
    # A channel slice of an (H, W, C) array is not C-contiguous; OpenEXR would misread it.
    stack = rng.normal(size=(8, 11, 4)).astype(np.float32)
    io.write_exr(tmp_path / "slice.exr", stack[:, :, 1])
    io.write_exr(tmp_path / "slice_rgb.exr", stack[:, ::-1, 1:])
    _assert_bitwise_equal(io.read_exr(tmp_path / "slice.exr"), stack[:, :, 1].copy())
    _assert_bitwise_equal(io.read_exr(tmp_path / "slice_rgb.exr"), stack[:, ::-1, 1:].copy())


def test_exr_casts_to_float32(tmp_path):
    image = np.array([[0.1, -2.5], [1e-3, 7.0]], dtype=np.float64)
    io.write_exr(tmp_path / "f64.exr", image)
    _assert_bitwise_equal(io.read_exr(tmp_path / "f64.exr"), image.astype(np.float32))
    io.write_exr(tmp_path / "int.exr", np.array([[1, -2]], dtype=np.int64))
    _assert_bitwise_equal(io.read_exr(tmp_path / "int.exr"), np.array([[1, -2]], np.float32))


def test_exr_is_zip_compressed_and_creates_parents(tmp_path):
    path = tmp_path / "a" / "b" / "img.exr"
    io.write_exr(path, np.zeros((4, 4, 3), np.float32))
    with OpenEXR.File(str(path), header_only=True) as exr_file:
        header = exr_file.header()
        assert header["compression"] == OpenEXR.ZIP_COMPRESSION
        assert [c.name for c in header["channels"]] == ["B", "G", "R"]  # stored sorted
    with OpenEXR.File(str(path), separate_channels=True) as exr_file:
        # Raw stored pixel type, before read_exr's cast: FLOAT, not HALF.
        assert all(c.pixels.dtype == np.float32 for c in exr_file.channels().values())


def test_exr_from_other_programs_uses_rgb_then_stored_order(tmp_path):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    r, g, b = (np.full((2, 3), value, np.float32) for value in (1.0, 2.0, 3.0))
    OpenEXR.File(header, {"B": b, "R": r, "G": g}).write(str(tmp_path / "rgb.exr"))
    np.testing.assert_array_equal(io.read_exr(tmp_path / "rgb.exr")[0, 0], [1.0, 2.0, 3.0])

    OpenEXR.File(header, {"z": r, "a": g, "m": b}).write(str(tmp_path / "abc.exr"))
    assert list(io.read_exr_channels(tmp_path / "abc.exr")) == ["a", "m", "z"]
    np.testing.assert_array_equal(io.read_exr(tmp_path / "abc.exr")[0, 0], [2.0, 3.0, 1.0])


def test_exr_half_channels_are_read_as_float32(tmp_path):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    half = np.array([[0.5, -1.25]], dtype=np.float16)
    OpenEXR.File(header, {"Y": half}).write(str(tmp_path / "half.exr"))
    result = io.read_exr(tmp_path / "half.exr")
    assert result.dtype == np.float32
    np.testing.assert_array_equal(result, [[0.5, -1.25]])


@pytest.mark.parametrize(
    "image, channels, match",
    [
        (np.zeros(5, np.float32), None, r"shape \(5,\)"),
        (np.zeros((2, 2, 2, 2), np.float32), None, r"shape \(2, 2, 2, 2\)"),
        (np.zeros((0, 3), np.float32), None, "empty"),
        (np.zeros((2, 2, 4), np.float32), None, "4 channels"),
        (np.zeros((2, 2, 3), np.float32), ["R", "G"], r"2 channel names \['R', 'G'\]"),
        (np.zeros((2, 2), np.float32), ["A", "B"], "2 channel names"),
        (np.zeros((2, 2, 2), np.float32), ["V", "V"], r"unique.*\['V', 'V'\]"),
        (np.zeros((2, 2, 2), np.float32), ["V", ""], "non-empty"),
        (np.zeros((2, 2), np.complex64), None, "complex64"),
    ],
)
def test_write_exr_rejects_bad_input(tmp_path, image, channels, match):
    with pytest.raises(ValueError, match=match):
        io.write_exr(tmp_path / "bad.exr", image, channels=channels)
    assert not (tmp_path / "bad.exr").exists()


def test_read_exr_missing_file_names_path(tmp_path):
    path = tmp_path / "nope" / "missing.exr"
    for reader in (io.read_exr, io.read_exr_channels):
        with pytest.raises(FileNotFoundError, match="missing.exr"):
            reader(path)


def test_read_exr_malformed_file_names_path(tmp_path, capfd):
    garbage = tmp_path / "garbage.exr"
    garbage.write_bytes(b"this is not an EXR file")
    with pytest.raises(ValueError, match="garbage.exr"):
        io.read_exr(garbage)

    # A valid header with its pixel data cut off halfway.
    full = tmp_path / "full.exr"
    io.write_exr(full, np.random.default_rng(0).random((200, 300), dtype=np.float32))
    truncated = tmp_path / "truncated.exr"
    data = full.read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="truncated.exr") as caught:
        io.read_exr_channels(truncated)
    assert "(OpenEXR: (EXR_ERR_" in str(caught.value)  # the library's reason, in the one message
    assert capfd.readouterr() == ("", "")  # and not printed on stdout or stderr beside it


# --------------------------------------------------------------------------------- NPY

def test_npy_round_trip_creates_parents_and_keeps_path(tmp_path, rng):
    array = rng.normal(size=(3, 4, 2))
    path = io.write_npy(tmp_path / "deep" / "dir" / "data.bin", array)
    assert path == tmp_path / "deep" / "dir" / "data.bin"  # no ".npy" appended
    result = io.read_npy(path)
    assert result.dtype == array.dtype
    np.testing.assert_array_equal(result, array)


def test_read_npy_errors_name_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="absent.npy"):
        io.read_npy(tmp_path / "absent.npy")
    (tmp_path / "junk.npy").write_bytes(b"\x00\x01junk")
    with pytest.raises(ValueError, match="junk.npy"):
        io.read_npy(tmp_path / "junk.npy")


# --------------------------------------------------------------------------------- dispatch

@pytest.mark.parametrize("name", ["img.exr", "IMG.EXR"])
def test_write_image_dispatches_exr(tmp_path, name):
    image = np.array([[1.0, -2.0], [np.nan, 4.0]], np.float32)
    io.write_image(tmp_path / name, image)
    _assert_bitwise_equal(io.read_exr(tmp_path / name), image)


def test_write_image_dispatches_npy(tmp_path):
    array = np.arange(6, dtype=np.int16).reshape(2, 3)
    io.write_image(tmp_path / "a.npy", array)
    result = io.read_npy(tmp_path / "a.npy")
    assert result.dtype == np.int16
    np.testing.assert_array_equal(result, array)


@pytest.mark.parametrize("name", ["img.png", "img", "img.exr.txt"])
def test_write_image_rejects_other_suffixes(tmp_path, name):
    with pytest.raises(ValueError, match="'.exr' or '.npy'"):
        io.write_image(tmp_path / name, np.zeros((2, 2)))
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------- JSON

def test_json_round_trip_converts_numpy(tmp_path):
    meta = {
        "spp": np.int64(64),
        "fov_deg": np.float32(39.5),
        "flag": np.bool_(True),
        "resolution": np.array([640, 480], dtype=np.int32),
        "matrix": np.eye(2),
        "shape": (3, 4),
        "output": Path("out/img.exr"),
        "nested": [{"value": np.float64(0.25)}],
        np.str_("numpy_key"): None,
    }
    path = io.write_json(tmp_path / "meta" / "run.json", meta)
    assert path.is_file()
    assert io.read_json(path) == {
        "spp": 64,
        "fov_deg": 39.5,
        "flag": True,
        "resolution": [640, 480],
        "matrix": [[1.0, 0.0], [0.0, 1.0]],
        "shape": [3, 4],
        "output": str(Path("out/img.exr")),
        "nested": [{"value": 0.25}],
        "numpy_key": None,
    }
    assert isinstance(io.read_json(path)["spp"], int)


def test_json_non_finite_round_trip(tmp_path):
    io.write_json(tmp_path / "nan.json", {"bias": np.float32("nan"), "max": float("inf")})
    result = io.read_json(tmp_path / "nan.json")
    assert np.isnan(result["bias"]) and result["max"] == float("inf")


def test_json_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="gone.json"):
        io.read_json(tmp_path / "gone.json")
    (tmp_path / "broken.json").write_text("{\"a\": 1,")
    with pytest.raises(ValueError, match="broken.json"):
        io.read_json(tmp_path / "broken.json")
    with pytest.raises(TypeError):
        io.write_json(tmp_path / "complex.json", {"z": 1 + 2j})
    assert not (tmp_path / "complex.json").exists()  # nothing half-written


def test_a_file_of_another_kind_is_named_as_such(tmp_path):
    """numpy's own message for a text file was "This file contains pickled (object) data"."""
    junk = tmp_path / "record.npz"
    junk.write_text("hello\n")
    for read, what in ((io.read_record, "a response record"), (io.read_npy, "a .npy array")):
        with pytest.raises(ValueError, match=f"as {what}.*: it is not one \\(it starts with b'hel") as info:
            read(junk)
        assert "pickled" not in str(info.value)
