"""Built-in scenes: every one builds and renders, and its ground-truth velocity follows the
motion it claims (merry-go-round, falling box, dominoes, rolling glass sphere)."""

import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof.tracing.path import place_camera_ray
from dopplertof import scenes

G = scenes.STANDARD_GRAVITY_M_S2
EXPOSURE_S = 1.5e-3
# Ground truth is a pixel's average over its samples' positions: enough of them that the
# average is the pixel centre's value to ~0.01 m/s where velocity varies 0.25 m/s a pixel.
GT_SPP = 128


def _pixel_hits(scene, time_s):
    """What the centre of each pixel sees at ``time_s``: body index (H, W; 0 static,
    b + 1 for ``scene.bodies[b]``, −1 nothing), hit point (H, W, 3) and unit ray
    direction (H, W, 3), world space."""
    import mitsuba as mi

    width, height = scene.resolution
    index = np.arange(width * height)
    film = mi.Point2f(((index % width) + 0.5) / width, ((index // width) + 0.5) / height)
    ray, _ = scene.sensor.sample_ray(0.0, 0.5, film, mi.Point2f(0.5, 0.5))
    times = mi.Float64(np.full(width * height, time_s))
    ray, _ = place_camera_ray(scene, mi.Ray3f(ray), mi.Vector3d(ray.o), times)  # where a moving camera is
    hit = scene.intersect(ray, times)
    valid = hit.si.is_valid().numpy()
    body = np.where(valid, hit.body.numpy().astype(np.int64), -1).reshape(height, width)
    p = np.stack([c.numpy() for c in (hit.si.p.x, hit.si.p.y, hit.si.p.z)], axis=-1).reshape(height, width, 3)
    d = np.stack([c.numpy() for c in (ray.d.x, ray.d.y, ray.d.z)], axis=-1).reshape(height, width, 3)
    return body, p, d


def _body_number(scene, name):
    """Body number (as in ``_pixel_hits``) of the body holding shape ``name``: shapes that
    share a motion are one body, named after all of them (``"a, b, c"``)."""
    shapes = [b.name.split(", ") for b in scene.bodies]
    numbers = [i + 1 for i, names in enumerate(shapes) if name in names]
    assert numbers, shapes
    return numbers[0]


def _interior(body, number):
    """Pixels whose centre and 8 neighbours' centres all see body ``number`` (so the whole
    pixel footprint does)."""
    mask = body == number
    inner = mask.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            inner &= np.roll(np.roll(mask, dy, axis=0), dx, axis=1)
    inner[[0, -1], :] = False
    inner[:, [0, -1]] = False
    return inner


def _bsdf_names(scene):
    shapes = list(scene.static.shapes()) + [s for b in scene.bodies for s in b.scene.shapes()]
    return {s.bsdf().class_name() for s in shapes if s.bsdf() is not None}


# ----------------------------------------------------------------------------------------
# Every scene


@pytest.mark.parametrize("name", list(scenes.SCENES))
def test_every_scene_builds_and_renders_with_moving_bodies_in_view(name):
    scene = scenes.build(name, resolution=24)
    assert scene.resolution == (24, 24)
    assert scene.bodies, "a built-in scene has something moving"
    t = min(0.4 * scenes.clip_duration(name), max(0.0, scenes.clip_duration(name) - EXPOSURE_S))
    # 16 spp: at 4 the median over the body pixels of the area-lit Cornell box scatters
    # about the bound (0.013–0.028 over seeds 0–5), at 16 it stays above (0.022–0.030).
    res = dt.render(scene, cameras=[dt.Camera(heterodyne=1.0)], spp=16, max_depth=3, exposure_start=t)
    for image in (res.intensity, res.stderr, res.measurements, res.measurement_stderr, res.coverage):
        assert np.all(np.isfinite(image))
    hit = res.coverage > 0
    assert hit.mean() > 0.5, "the scene fills most of the frame"
    for image in (res.depth, res.velocity, res.point_velocity):
        assert np.all(np.isfinite(image[hit]))
    assert res.intensity.mean() > 0.05, "the scene is lit"
    body, _, _ = _pixel_hits(scene, t)
    lit = res.intensity.mean(axis=-1)
    on_bodies = body > 0
    assert on_bodies.sum() >= 3, "moving bodies are in view"
    assert np.median(lit[on_bodies]) > 0.02, "the moving bodies are lit"


@pytest.mark.parametrize("name", list(scenes.SCENES))
def test_clip_duration_is_positive(name):
    duration = scenes.clip_duration(name)
    assert math.isfinite(duration) and duration > 0


def test_clip_duration_follows_the_scene_parameters():
    assert scenes.clip_duration("cornell-box") == pytest.approx(1.5e-3)
    assert scenes.clip_duration("cornell-box-area", exposure=3e-3) == pytest.approx(3e-3)
    assert scenes.clip_duration("rotating") == pytest.approx(2 * math.pi * 1.2 / 3.0)
    assert scenes.clip_duration("rotating", rim_speed=6.0) == pytest.approx(2 * math.pi * 1.2 / 6.0)
    assert scenes.clip_duration("falling-box", drop_height=2.0) == pytest.approx(math.sqrt(2 * 2.0 / G))
    assert scenes.clip_duration("glossy", speed=4.0) == pytest.approx(0.5)
    assert scenes.clip_duration("dominoes", count=12) > scenes.clip_duration("dominoes", count=6)
    assert scenes.clip_duration("rotating", resolution=16) == scenes.clip_duration("rotating")


def test_unknown_scene_or_parameter_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown scene 'merry'.*rotating"):
        scenes.clip_duration("merry")
    with pytest.raises(ValueError, match="unknown scene 'merry'"):
        scenes.build("merry")
    with pytest.raises(ValueError, match=r"no parameter\(s\) \['speed'\]"):
        scenes.clip_duration("rotating", speed=3.0)
    with pytest.raises(ValueError, match="count must be a positive integer, got 0"):
        scenes.clip_duration("dominoes", count=0)


@pytest.mark.parametrize("name", list(scenes.SCENES))
@pytest.mark.parametrize("resolution", [0, -8, 2.5, True, "64"])
def test_bad_resolution_is_a_clear_error(name, resolution):
    with pytest.raises(ValueError, match=f"resolution must be a positive integer, got {resolution!r}"):
        scenes.build(name, resolution=resolution)


@pytest.mark.parametrize(
    "name, kwargs, message",
    [
        ("rotating", {"rim_speed": -1.0}, "rim_speed must be a finite number > 0, got -1.0"),
        ("rotating", {"radius": float("nan")}, "radius must be"),
        ("falling-box", {"drop_height": 0.0}, "drop_height must be"),
        ("falling-box", {"keyframes": 0}, "keyframes must be a positive integer"),
        ("falling-box", {"spin_deg": 720.0, "keyframes": 2}, "spin_deg=720.0 is too much"),
        ("dominoes", {"count": 0}, "count must be a positive integer, got 0"),
        ("dominoes", {"spacing": 0.05}, "spacing=0.05 m must exceed the thickness"),
        ("dominoes", {"spacing": 1.0}, "could not knock each other over"),
        ("dominoes", {"push": 0.1}, "push=0.1 rad/s does not tip a domino"),
        ("glossy", {"speed": "fast"}, "speed must be a finite number > 0, got 'fast'"),
    ],
)
def test_bad_scene_parameters_are_clear_errors(name, kwargs, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        scenes.build(name, resolution=8, **kwargs)


# ----------------------------------------------------------------------------------------
# Ground-truth velocity against the motion each scene defines


def test_merry_go_round_spins_about_the_vertical_axis():
    scene = scenes.rotating(resolution=32, radius=1.2, rim_speed=3.0)
    omega = np.array([0.0, 3.0 / 1.2, 0.0])
    res = dt.render(scene, spp=GT_SPP, max_depth=1)
    body, p, d = _pixel_hits(scene, 0.5 * EXPOSURE_S)
    merry_go_round = _body_number(scene, "platform-top")
    assert all(_body_number(scene, n) == merry_go_round for n in ("red-cube", "green-sphere", "yellow-post", "blue-sphere"))
    # The platform and its riders are one body: tell the platform's top by its height.
    on_top = (body == merry_go_round) & (np.abs(p[..., 1] - scenes.ROTATING_PLATFORM_HEIGHT_M) < 1e-3)
    top = _interior(on_top.astype(int), 1)
    assert top.sum() > 30
    expected = np.einsum("...k,...k", np.cross(omega, p), d)  # axis through the origin
    np.testing.assert_allclose(res.point_velocity[top], expected[top], rtol=0.03, atol=0.04)
    left, right = top & (p[..., 0] < -0.3), top & (p[..., 0] > 0.3)
    assert left.any() and right.any()
    # Counter-clockwise seen from above: the left side comes towards the camera.
    assert np.all(res.point_velocity[left] < 0) and np.all(res.point_velocity[right] > 0)
    assert res.point_velocity[right].max() > 1.0, "a few m/s at the rim, as the scene says"
    # A disc turning in its own plane does not change the distance along a pixel ray.
    np.testing.assert_allclose(res.velocity[top], 0.0, atol=1e-3)
    # The riders have a component along the rays: the D-ToF camera sees them move.
    riders = (body == merry_go_round) & (p[..., 1] > scenes.ROTATING_PLATFORM_HEIGHT_M + 1e-3)
    assert np.abs(res.velocity[riders]).max() > 1.0


def test_falling_box_falls_under_gravity_and_lands_flat():
    drop, size, spin_deg, segments = 1.5, 0.5, 90.0, 24
    scene = scenes.falling_box(resolution=32, drop_height=drop, size=size, spin_deg=spin_deg, keyframes=segments)
    (box,) = scene.bodies
    fall = math.sqrt(2 * drop / G)
    step = fall / segments
    t = (segments // 2 + 0.5) * step  # middle of a key interval: the velocity there is g·t

    centre = lambda time: box.motion.matrix(time)[:3, 3]  # noqa: E731
    h = 0.25 * step  # within the key interval (keys are float32: a tiny h would amplify that)
    np.testing.assert_allclose((centre(t + h) - centre(t - h)) / (2 * h), [0.0, -G * t, 0.0], atol=1e-4)
    # At rest on the floor after the fall: a face down, the lowest corner at y = 0.
    corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    for late in (fall, fall + 0.3):
        assert (box.motion.matrix(late) @ corners.T)[1].min() == pytest.approx(0.0, abs=1e-6)  # float32 transforms
    np.testing.assert_allclose(box.motion.matrix(fall + 0.3), box.motion.matrix(fall))

    res = dt.render(scene, spp=GT_SPP, max_depth=1, exposure_start=t - 0.5 * EXPOSURE_S)
    body, p, d = _pixel_hits(scene, t)
    inside = _interior(body, 1)
    assert inside.sum() >= 4
    omega = np.array([math.radians(spin_deg) / fall, 0.0, 0.0])
    c = np.array([0.0, drop + 0.5 * size - 0.5 * G * t * t, 0.0])
    v = np.array([0.0, -G * t, 0.0]) + np.cross(omega, p - c)
    expected = np.einsum("...k,...k", v, d)
    np.testing.assert_allclose(res.point_velocity[inside], expected[inside], rtol=0.03, atol=0.04)


def test_dominoes_topple_one_after_another_about_their_bottom_edges():
    count = 10
    scene = scenes.dominoes(resolution=32, count=count)
    assert [b.name for b in scene.bodies] == [f"domino-{j}" for j in range(count)]
    times, angles = scenes.domino_chain(count)
    starts = np.array([times[np.argmax(a > 0)] for a in angles])
    assert np.all(np.diff(starts) > 0), "one after another"
    assert angles[-1, -1] == pytest.approx(math.pi / 2), "the last one lies flat"
    assert np.all((angles[:-1, -1] > 0.2) & (angles[:-1, -1] < math.pi / 2)), "the others lean on the next one"
    assert np.all(np.diff(angles, axis=1) >= 0)

    # Each domino turns about its front bottom edge: that edge stays where it stood.
    edge = np.array([[1.0, -1.0, -1.0, 1.0], [1.0, -1.0, 1.0, 1.0]])
    for domino in scene.bodies:
        rest = domino.motion.matrix(-1.0) @ edge.T
        for key_time in domino.motion.times:
            np.testing.assert_allclose(domino.motion.matrix(key_time) @ edge.T, rest, atol=1e-6)

    t = 0.5 * starts[1]  # the first domino is tipping, the others still stand
    res = dt.render(scene, spp=4, max_depth=1, exposure_start=t)
    body, _, _ = _pixel_hits(scene, t + 0.5 * EXPOSURE_S)
    first, last = body == 1, body == count
    assert first.any() and last.any()
    assert np.abs(res.point_velocity[first]).max() > 0.1
    assert np.abs(res.velocity[first]).max() > 0.1
    standing = np.isin(body, np.arange(2, count + 1))
    assert np.all(res.point_velocity[standing] == 0.0) and np.all(res.velocity[standing] == 0.0)


def test_street_moves_the_camera_with_its_light_through_traffic():
    speed = 15.0
    scene = scenes.street(resolution=24, speed=speed)
    assert len(scene.bodies) == scenes.STREET_MOVING_BODIES and len(scene.lights) == 1 and scene.camera_motion is not None
    assert f"{len(scene.bodies)} moving bodies" in scenes.SCENES["street"][1]  # what `dopplertof scenes` says
    res = dt.render(scene, spp=GT_SPP, max_depth=1)
    body, _, d = _pixel_hits(scene, 0.5 * EXPOSURE_S)
    static = _interior(body, 0) & (res.coverage == 1)  # the whole footprint on static geometry
    # Seen from the car, static points come at -speed along the road (z): d/dt |p - c| = -v·d̂
    np.testing.assert_allclose(res.point_velocity[static], -speed * -d[static][:, 2], rtol=0.02, atol=0.05)
    assert np.all(np.abs(res.velocity_3d[static][:, 2] + speed) < 0.05 * speed)  # the camera looks (nearly) down the road


def test_glossy_has_conductors_a_dielectric_and_a_rolling_sphere():
    speed = 2.0
    scene = scenes.glossy(resolution=32, speed=speed)
    assert {"SmoothConductor", "RoughConductor", "SmoothDielectric", "SmoothDiffuse"} <= _bsdf_names(scene)

    t = 0.5
    res = dt.render(scene, spp=GT_SPP, max_depth=1, exposure_start=t - 0.5 * EXPOSURE_S)
    body, p, d = _pixel_hits(scene, t)
    sphere = _interior(body, _body_number(scene, "glass-sphere"))
    assert sphere.sum() >= 4
    radius = 0.3
    v = speed * np.array([0.8, 0.0, 0.6])
    omega = np.cross([0.0, 1.0, 0.0], v) / radius  # rolling: the contact point is at rest
    c = np.array([-1.4, radius, -0.1]) + v * t
    expected_point = np.einsum("...k,...k", v + np.cross(omega, p - c), d)
    np.testing.assert_allclose(res.point_velocity[sphere], expected_point[sphere], rtol=0.03, atol=0.04)
    # Spinning about its centre does not move a sphere's surface along the normal: the
    # camera sees the translation only, (n·v)/(n·d̂).
    n = (p - c) / radius
    expected_ray = (n @ v) / np.einsum("...k,...k", n, d)
    np.testing.assert_allclose(res.velocity[sphere], expected_ray[sphere], rtol=0.05, atol=0.05)
