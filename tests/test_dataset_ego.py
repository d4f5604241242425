"""Ego-motion in the dataset randomizer: a moving camera with its modulated light attached.

* The camera's motion is drawn last from the scene stream: a description with a moving
  camera differs from the static one of the same (seed, i) only in the camera's velocities,
  and the same (seed, i) gives the same description.
* ``build_scene`` gives the sensor a motion and attaches the light to it (the light stays
  at the aperture); a static camera keeps a static light in the world.
* The ground truth is relative to the camera: static geometry seen by a translating camera
  has ``velocity_3d`` = −Rᵀ v_camera, and ``moving_mask`` stays 0 (no body moves).
"""

import numpy as np
import pytest
from click.testing import CliRunner

from dopplertof.cli import main
from dopplertof.dataset import config as config_mod
from dopplertof.dataset import randomize
from dopplertof.dataset.sample import make_record, render_record

VARIANT = "llvm_ad_rgb"
EGO_KEYS = ("indoor_probability", "indoor_speed_m_s", "indoor_yaw_rate_rad_s", "street_probability", "street_speed_m_s", "street_yaw_rate_rad_s")
CAMERA_MOTION_KEYS = ("linear_velocity_m_s", "angular_velocity_rad_s", "pivot_m")


def _ego(probability: float, **extra) -> dict:
    return {"ego": {"indoor_probability": probability, "street_probability": probability, **extra}}


def test_ego_motion_is_drawn_last_and_deterministic():
    moving_cfg, static_cfg = config_mod.validate(_ego(1.0)), config_mod.validate(_ego(0.0))
    kinds = set()
    for i in range(8):
        rec = make_record(moving_cfg, 3, i, VARIANT)
        assert rec == make_record(moving_cfg, 3, i, VARIANT)  # a function of (seed, i)
        kind, cam = rec["scene"]["kind"], rec["scene"]["camera"]
        kinds.add(kind)
        v, w = np.array(cam["linear_velocity_m_s"]), np.array(cam["angular_velocity_rad_s"])
        lo, hi = moving_cfg["ego"][f"{kind}_speed_m_s"]
        assert lo <= np.linalg.norm(v) <= hi and v[1] == 0  # horizontal
        if kind == "street":
            assert v[0] == 0 and v[2] < 0  # along the road, the way the camera looks
        lo, hi = moving_cfg["ego"][f"{kind}_yaw_rate_rad_s"]
        assert w[0] == w[2] == 0 and lo <= abs(w[1]) <= hi  # a yaw
        assert cam["pivot_m"] == cam["origin"]
        assert rec["camera_motion"] == {"moving": True, "speed_m_s": float(np.linalg.norm(v)), "yaw_rate_rad_s": float(w[1])}
        # the static camera of the same (seed, i): the same scene but for the camera's velocities
        still = make_record(static_cfg, 3, i, VARIANT)
        assert still["scene"]["camera"]["linear_velocity_m_s"] == still["scene"]["camera"]["angular_velocity_rad_s"] == [0.0] * 3
        assert not still["camera_motion"]["moving"]
        for scene in (rec["scene"], still["scene"]):
            for key in CAMERA_MOTION_KEYS:
                del scene["camera"][key]
        assert rec["scene"] == still["scene"]
    assert kinds == {"indoor", "street"}


def test_a_moving_camera_carries_its_light():
    cfg = config_mod.validate(_ego(1.0))
    desc = make_record(cfg, 3, 1, VARIANT)["scene"]
    scene = randomize.build_scene(desc, 8)
    cam = desc["camera"]
    v = np.array(cam["linear_velocity_m_s"])
    assert scene.camera_motion is not None and not scene.camera_motion.is_static()
    np.testing.assert_array_equal(scene.camera_motion.linear_velocity, v)
    assert len(scene.lights) == 1 and len(scene.static.emitters()) == 0  # attached, not in the world
    for t in (0.0, 1e-3):  # the light stays at the aperture, which moves at v whatever the yaw
        np.testing.assert_allclose(scene.lights[0].motion.matrix(t)[:3, 3], np.array(cam["origin"]) + v * t, atol=1e-5)
    static = randomize.build_scene(make_record(config_mod.validate(_ego(0.0)), 3, 1, VARIANT)["scene"], 8)
    assert static.camera_motion is None and static.lights == [] and len(static.static.emitters()) == 1


def test_static_pixels_see_the_camera_velocity():
    """A translating camera in a room without moving bodies: every hit pixel's relative
    velocity is −Rᵀ v_camera (camera frame), and no pixel is on a moving body."""
    cfg = config_mod.validate({
        **_ego(1.0, indoor_yaw_rate_rad_s=[0.0, 0.0]),
        "scene": {"kinds": {"indoor": 1.0}},
        "bodies": {"count": [1, 2], "moving_probability": 0.0},
        "render": {"resolution": 12, "spp": 4},
    })  # fmt: skip
    record = make_record(cfg, 2, 0, VARIANT)
    cam = record["scene"]["camera"]
    assert record["scene"]["bodies"] == [] and record["camera_motion"]["moving"]
    arrays, _, _ = render_record(record, ("depth", "velocity", "velocity_3d", "instance_id", "moving_mask"))
    hit = np.isfinite(arrays["depth"])
    assert hit.all()  # a closed room
    expected = -randomize.camera_rotation(cam).T @ np.array(cam["linear_velocity_m_s"])
    np.testing.assert_allclose(arrays["velocity_3d"][hit], np.broadcast_to(expected, (hit.sum(), 3)), atol=1e-4)
    assert np.all(arrays["instance_id"] == -1) and not arrays["moving_mask"].any()
    assert np.abs(arrays["velocity"][hit]).max() > 0.1 * np.linalg.norm(expected)  # the radial velocity sees it too


def test_default_config_prints_the_ego_keys():
    res = CliRunner().invoke(main, ["dataset", "config", "--print"])
    assert res.exit_code == 0
    assert "\n[ego]  # " in res.output
    for key in EGO_KEYS:
        assert f"\n{key} = " in res.output, key
    assert config_mod.defaults()["ego"] == {"indoor_probability": 0.3, "indoor_speed_m_s": [0.5, 2.0], "indoor_yaw_rate_rad_s": [0.0, 0.5],
                                            "street_probability": 0.5, "street_speed_m_s": [5.0, 20.0], "street_yaw_rate_rad_s": [0.0, 0.1]}


@pytest.mark.parametrize(
    "ego, message",
    [
        ({"street_probability": 1.5}, "config key 'ego.street_probability' is a probability in [0, 1], got 1.5"),
        ({"indoor_speed_m_s": [2.0, 0.5]}, "config key 'ego.indoor_speed_m_s': range min 2.0 > max 0.5"),
        ({"street_yaw_rate_rad_s": [-0.1, 0.1]}, "config key 'ego.street_yaw_rate_rad_s' must not be negative"),
        ({"indoor_probability": "often"}, "config key 'ego.indoor_probability' must be a finite number"),
        ({"speed_m_s": [1.0, 2.0]}, "unknown config key 'ego.speed_m_s'"),
    ],
)
def test_bad_ego_config_is_a_value_error_naming_the_key(ego, message):
    with pytest.raises(ValueError) as info:
        config_mod.validate({"ego": ego})
    assert message in str(info.value)
