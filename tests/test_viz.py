"""Tests for dopplertof.viz: sRGB curve, symmetric signed colour maps, PNG/GIF/figure output."""

import imageio.v3 as iio
import matplotlib
import numpy as np
import pytest

from dopplertof import viz


def _png_size(path):
    """(height, width) of a PNG file, read back from disk."""
    return iio.imread(path).shape[:2]


def _cmap_rgb8(name, t):
    """The uint8 RGB colour of matplotlib colour map ``name`` at position t in [0, 1]."""
    return np.asarray(matplotlib.colormaps[name](t, bytes=True)[:3])


# --------------------------------------------------------------------------------- sRGB

def test_linear_to_srgb_endpoints_and_reference_values():
    np.testing.assert_allclose(viz.linear_to_srgb([0.0, 1.0]), [0.0, 1.0], atol=1e-12)
    # IEC 61966-2-1 reference values (a pure 2.2 gamma would give 0.4587 and 0.7297).
    np.testing.assert_allclose(viz.linear_to_srgb([0.18, 0.5]), [0.46135613, 0.73535698],
                               atol=1e-6)
    # Linear segment below the threshold.
    np.testing.assert_allclose(viz.linear_to_srgb(0.001), 0.01292, atol=1e-12)


def test_linear_to_srgb_is_continuous_and_monotonic_at_threshold():
    threshold = 0.0031308
    below = viz.linear_to_srgb(np.nextafter(threshold, 0.0))
    above = viz.linear_to_srgb(np.nextafter(threshold, 1.0))
    at = viz.linear_to_srgb(threshold)
    assert abs(above - below) < 1e-6
    np.testing.assert_allclose(at, 12.92 * threshold, atol=1e-12)
    x = np.linspace(0.0, 0.01, 10001)
    assert np.all(np.diff(viz.linear_to_srgb(x)) > 0)


def test_to_srgb8_endpoints_clipping_and_nan():
    image = np.array([[0.0, 1.0, 2.0, -0.5, np.nan, np.inf, -np.inf, 0.18]])
    rgb8 = viz.to_srgb8(image)
    assert rgb8.dtype == np.uint8 and rgb8.shape == (1, 8, 3)
    np.testing.assert_array_equal(rgb8[0, :, 0], [0, 255, 255, 0, 0, 255, 0, 118])
    # Grey input is replicated to all three channels.
    np.testing.assert_array_equal(rgb8[..., 0], rgb8[..., 1])
    np.testing.assert_array_equal(rgb8[..., 0], rgb8[..., 2])


def test_to_srgb8_threshold_values_agree_across_the_boundary():
    threshold = 0.0031308
    image = np.array([[np.nextafter(threshold, 0.0), threshold, np.nextafter(threshold, 1.0)]])
    values = viz.to_srgb8(image)[0, :, 0]
    assert values[0] == values[1] == values[2] == round(12.92 * threshold * 255)


def test_to_srgb8_rgb_and_exposure():
    image = np.zeros((2, 3, 3))
    image[..., 0], image[..., 1], image[..., 2] = 0.25, 0.5, 1.0
    rgb8 = viz.to_srgb8(image, exposure=2.0)  # -> 0.5, 1.0, 2.0 (clipped)
    assert rgb8.shape == (2, 3, 3)
    np.testing.assert_array_equal(rgb8[0, 0], [188, 255, 255])


@pytest.mark.parametrize("exposure", [0.0, -1.0, np.nan, np.inf])
def test_to_srgb8_rejects_bad_exposure(exposure):
    with pytest.raises(ValueError, match="exposure"):
        viz.to_srgb8(np.zeros((2, 2)), exposure=exposure)


@pytest.mark.parametrize("shape", [(4,), (2, 2, 4), (2, 2, 1), (0, 3)])
def test_to_srgb8_rejects_bad_shape(shape):
    with pytest.raises(ValueError, match="shape"):
        viz.to_srgb8(np.zeros(shape))


# --------------------------------------------------------------------------------- signed maps

def test_auto_vmax():
    values = np.linspace(-1.0, 1.0, 1001)
    values[0] = -1000.0  # one outlier must not set the range
    assert viz.auto_vmax(values) == pytest.approx(np.percentile(np.abs(values), 99))
    assert viz.auto_vmax(values) < 2.0
    assert viz.auto_vmax(np.zeros((3, 3))) == 1.0
    assert viz.auto_vmax(np.full((3, 3), np.nan)) == 1.0
    sparse = np.zeros(1000)
    sparse[3] = -0.5  # 99th percentile is 0: fall back to the largest |x|
    assert viz.auto_vmax(sparse) == 0.5
    assert viz.auto_vmax([np.array([1.0, np.inf]), np.array([-3.0])]) == pytest.approx(
        np.percentile([1.0, 3.0], 99))


@pytest.mark.parametrize("cmap", ["RdBu_r", "coolwarm", "PiYG"])
def test_signed_map_zero_is_centre_and_ends_are_symmetric(cmap):
    v = 2.5
    image = np.array([[0.0, v, -v, 10 * v, -10 * v, np.inf, -np.inf]])
    rgb8 = viz.signed_to_rgb8(image, vmax=v, cmap=cmap)
    assert rgb8.dtype == np.uint8 and rgb8.shape == (1, 7, 3)
    centre, top, bottom = (_cmap_rgb8(cmap, t) for t in (0.5, 1.0, 0.0))
    np.testing.assert_array_equal(rgb8[0, 0], centre)
    for i in (1, 3, 5):  # +v and everything beyond
        np.testing.assert_array_equal(rgb8[0, i], top)
    for i in (2, 4, 6):  # -v and everything beyond
        np.testing.assert_array_equal(rgb8[0, i], bottom)


def test_signed_map_default_range_is_symmetric_for_skewed_data():
    # Data in [-1, 3]: a min/max normalisation would put 0 at a quarter, not the centre.
    image = np.linspace(-1.0, 3.0, 401).reshape(1, -1)
    image[0, 100] = 0.0
    rgb8 = viz.signed_to_rgb8(image)
    np.testing.assert_array_equal(rgb8[0, 100], _cmap_rgb8("RdBu_r", 0.5))
    # RdBu_r: positive is red, negative blue.
    assert rgb8[0, -1, 0] > rgb8[0, -1, 2]
    assert rgb8[0, 0, 2] > rgb8[0, 0, 0]
    # +1 and -1 sit symmetrically around the centre of the map.
    vmax = viz.auto_vmax(image)
    np.testing.assert_array_equal(rgb8[0, 200], _cmap_rgb8("RdBu_r", (1.0 + vmax) / (2 * vmax)))
    np.testing.assert_array_equal(rgb8[0, 0], _cmap_rgb8("RdBu_r", (-1.0 + vmax) / (2 * vmax)))


def test_signed_map_nan_is_grey():
    rgb8 = viz.signed_to_rgb8(np.array([[np.nan, 0.0, 1.0]]))
    np.testing.assert_array_equal(rgb8[0, 0], viz.NAN_RGB8)
    assert not np.array_equal(rgb8[0, 1], viz.NAN_RGB8)


def test_signed_map_rejects_rgb_and_bad_arguments():
    with pytest.raises(ValueError, match=r"\(4, 5, 3\).*luminance"):
        viz.signed_to_rgb8(np.zeros((4, 5, 3)))
    with pytest.raises(ValueError, match=r"\(7,\)"):
        viz.signed_to_rgb8(np.zeros(7))
    for vmax in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="vmax"):
            viz.signed_to_rgb8(np.zeros((2, 2)), vmax=vmax)
    with pytest.raises(ValueError, match="not_a_cmap"):
        viz.signed_to_rgb8(np.zeros((2, 2)), cmap="not_a_cmap")


# --------------------------------------------------------------------------------- PNG

def test_save_png_pixel_exact(tmp_path):
    picture = np.random.default_rng(0).integers(0, 256, size=(13, 21, 3), dtype=np.uint8)
    path = viz.save_png(tmp_path / "sub" / "p.png", picture)
    np.testing.assert_array_equal(iio.imread(path), picture)
    grey = picture[..., 0]
    viz.save_png(tmp_path / "g.png", grey)
    np.testing.assert_array_equal(iio.imread(tmp_path / "g.png"), grey)


def test_save_png_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match="float64"):
        viz.save_png(tmp_path / "f.png", np.zeros((2, 2, 3)))
    with pytest.raises(ValueError, match=r"\(2, 2, 2\)"):
        viz.save_png(tmp_path / "s.png", np.zeros((2, 2, 2), np.uint8))
    with pytest.raises(ValueError, match="x.jpg"):
        viz.save_png(tmp_path / "x.jpg", np.zeros((2, 2, 3), np.uint8))


def test_save_intensity_png(tmp_path):
    image = np.linspace(0.0, 1.0, 15 * 9).reshape(15, 9)
    viz.save_intensity_png(tmp_path / "i.png", image, exposure=0.5)
    read = iio.imread(tmp_path / "i.png")
    assert read.shape[:2] == (15, 9)
    np.testing.assert_array_equal(read[..., :3], viz.to_srgb8(image, exposure=0.5))


def test_save_signed_png_without_colorbar_is_the_map(tmp_path):
    image = np.linspace(-2.0, 5.0, 11 * 17).reshape(11, 17)
    vmax = viz.save_signed_png(tmp_path / "s.png", image)
    assert vmax == pytest.approx(viz.auto_vmax(image))
    read = iio.imread(tmp_path / "s.png")
    assert read.shape[:2] == (11, 17)
    np.testing.assert_array_equal(read[..., :3], viz.signed_to_rgb8(image, vmax=vmax))


def test_save_signed_png_with_colorbar(tmp_path):
    image = np.linspace(-2.0, 2.0, 30 * 40).reshape(30, 40)
    vmax = viz.save_signed_png(tmp_path / "cb.png", image, vmax=1.5, colorbar=True,
                               title="phase", unit="rad")
    assert vmax == 1.5
    height, width = _png_size(tmp_path / "cb.png")
    assert height > 30 and width > 40  # a figure, larger than the map itself


def test_save_velocity_png(tmp_path):
    velocity = np.linspace(-3.0, 3.0, 20 * 25).reshape(20, 25)
    velocity[:3] = np.nan
    vmax = viz.save_velocity_png(tmp_path / "v" / "vel.png", velocity)
    assert vmax == pytest.approx(viz.auto_vmax(velocity))
    assert (tmp_path / "v" / "vel.png").stat().st_size > 1000
    height, width = _png_size(tmp_path / "v" / "vel.png")
    assert height > 20 and width > 25
    with pytest.raises(ValueError, match="luminance"):
        viz.save_velocity_png(tmp_path / "rgb.png", np.zeros((4, 4, 3)))


def test_comparison_figure_shares_one_range(tmp_path):
    rng = np.random.default_rng(3)
    truth = rng.normal(size=(24, 32))
    reconstructed = truth + 2.0 * rng.normal(size=truth.shape)
    images = {"reconstructed": reconstructed, "ground truth": truth}
    vmax = viz.comparison_figure(tmp_path / "cmp.png", images, title="velocity", unit="m/s")
    assert vmax == pytest.approx(viz.auto_vmax([reconstructed, truth]))
    assert vmax > viz.auto_vmax(truth)  # the wider panel sets the shared range
    height, width = _png_size(tmp_path / "cmp.png")
    assert width > height > 24

    assert viz.comparison_figure(tmp_path / "fixed.png", images, vmax=0.7) == 0.7
    unsigned = viz.comparison_figure(tmp_path / "u.png", {"a": np.abs(truth)}, signed=False)
    assert unsigned > 0 and (tmp_path / "u.png").stat().st_size > 0


def test_comparison_figure_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match="at least one"):
        viz.comparison_figure(tmp_path / "e.png", {})
    with pytest.raises(ValueError, match="'rgb'.*luminance"):
        viz.comparison_figure(tmp_path / "e.png", {"ok": np.zeros((2, 2)),
                                                   "rgb": np.zeros((2, 2, 3))})
    assert not (tmp_path / "e.png").exists()


def test_plot_curves(tmp_path):
    spp = np.array([1, 4, 16, 64, 256])
    rmse = 1.0 / np.sqrt(spp)
    curves = {"ours": (rmse, 0.1 * rmse), "baseline": (2 * rmse, None), "bare": 3 * rmse}
    path = viz.plot_curves(tmp_path / "plots" / "rmse.png", spp, curves, xlabel="spp",
                           ylabel="RMSE (m/s)", logy=True, title="convergence")
    assert path.stat().st_size > 1000
    height, width = _png_size(path)
    assert height > 100 and width > 100
    # Bands reaching below zero on a log axis are clipped, not an error.
    viz.plot_curves(tmp_path / "lin.png", spp, {"a": (rmse, 2 * rmse)}, "spp", "RMSE",
                    logy=True)
    assert (tmp_path / "lin.png").stat().st_size > 0


def test_plot_curves_rejects_bad_input(tmp_path):
    x = np.arange(4)
    with pytest.raises(ValueError, match=r"'a'.*\(3,\)"):
        viz.plot_curves(tmp_path / "p.png", x, {"a": (np.ones(3), None)}, "x", "y")
    with pytest.raises(ValueError, match=r"'b': yerr.*\(5,\)"):
        viz.plot_curves(tmp_path / "p.png", x, {"b": (np.ones(4), np.ones(5))}, "x", "y")
    with pytest.raises(ValueError, match="-1"):
        viz.plot_curves(tmp_path / "p.png", x, {"c": (np.ones(4), -np.ones(4))}, "x", "y")
    with pytest.raises(ValueError, match="at least one"):
        viz.plot_curves(tmp_path / "p.png", x, {}, "x", "y")
    with pytest.raises(ValueError, match=r"\(2, 2\)"):
        viz.plot_curves(tmp_path / "p.png", np.ones((2, 2)), {"a": np.ones(4)}, "x", "y")


# --------------------------------------------------------------------------------- GIF

def test_write_gif_frame_count_and_size(tmp_path):
    frames = [viz.to_srgb8(np.full((12, 16), i / 6.0)) for i in range(7)]
    path = viz.write_gif(tmp_path / "anim" / "a.gif", frames, fps=10)
    read = iio.imread(path, index=None)
    assert read.shape[:3] == (7, 12, 16)
    assert iio.immeta(path)["duration"] == 100  # ms per frame at 10 fps


@pytest.mark.parametrize("fps", [0, -5, np.nan, np.inf])
def test_write_gif_rejects_bad_fps(tmp_path, fps):
    with pytest.raises(ValueError, match="fps"):
        viz.write_gif(tmp_path / "a.gif", [np.zeros((2, 2, 3), np.uint8)], fps=fps)


def test_write_gif_rejects_bad_frames(tmp_path):
    good = np.zeros((4, 4, 3), np.uint8)
    with pytest.raises(ValueError, match="at least one"):
        viz.write_gif(tmp_path / "a.gif", [], fps=5)
    with pytest.raises(ValueError, match=r"frame 1 has shape \(4, 5, 3\)"):
        viz.write_gif(tmp_path / "a.gif", [good, np.zeros((4, 5, 3), np.uint8)], fps=5)
    with pytest.raises(ValueError, match="frame 0 must be uint8"):
        viz.write_gif(tmp_path / "a.gif", [good.astype(np.float32)], fps=5)
    with pytest.raises(ValueError, match=r"\(4, 4\)"):
        viz.write_gif(tmp_path / "a.gif", [good[..., 0]], fps=5)
    with pytest.raises(ValueError, match="a.mp4"):
        viz.write_gif(tmp_path / "a.mp4", [good], fps=5)
    assert list(tmp_path.iterdir()) == []
