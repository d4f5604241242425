"""Infinitely distant emitters (directional lights, environments) in D-ToF measurements:
their light is a plane wave, whose phase at a point x changes with ω·x (ω towards the
emitter), measured from a plane fixed per scene (tracing/path.py, plane_wave_leg_m).

* A plane moving into a directional light's wave shortens the light's leg at its speed
  along ω, whatever else is in the scene (a far sphere moves Mitsuba's own sample points,
  which used to set the leg: −30 m/s where −20 is physical).
* Under a constant environment, emitter sampling and BSDF sampling (escaped rays) give the
  same optical length to the same direction: the phase of a homodyne camera equals the
  plane-wave integral over the lit hemisphere.
"""

import math

import numpy as np
import pytest

import dopplertof as dt
from dopplertof.modulation import SPEED_OF_LIGHT_M_S
from scene_dicts import T

F_HZ = 30e6
K = 2 * math.pi * F_HZ / SPEED_OF_LIGHT_M_S  # rad per metre of optical length
SPEED_M_S = 10.0


def _scene(light, speed=SPEED_M_S, plane_at=(0.0, 0.0, 2.0), resolution=9, fov=20.0, **extra):
    """A camera at the origin looking along +z at a 10 m × 10 m diffuse plane facing it,
    approaching at ``speed``, lit by ``light``."""
    plane = {"type": "rectangle", "to_world": T().translate(list(plane_at)) @ T().rotate([0, 1, 0], 180) @ T().scale(5), "bsdf": {"type": "diffuse"}}
    if speed:
        plane["motion"] = {"type": "parametric", "linear_velocity": [0.0, 0.0, -speed]}
    return dt.load_scene({
        "type": "scene",
        "sensor": {"type": "perspective", "fov": fov, "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}}},
        "plane": plane, "light": light, **extra,
    })  # fmt: skip


def _phase(scene, start_s, spp=256, correlation="replay"):
    """The centre pixel's homodyne phase arg Σ e^{ikL} (rad), exposure 0.1 ms from ``start_s``."""
    cameras = [dt.Camera(modulation_frequency=F_HZ, heterodyne=0.0, phase=p, exposure=1e-4, exposure_start=start_s) for p in (0.0, math.pi / 2)]
    m = np.asarray(dt.render(scene, cameras, spp=spp, seed=3, max_depth=2, correlation=correlation).measurements, dtype=np.float64)
    centre = m.shape[1] // 2
    return math.atan2(-m[1, centre, centre], m[0, centre, centre])


def _length_rate_m_s(scene, dt_s=3.6e-3):
    """dL/dt of the centre pixel's optical length, from its phase at two instants."""
    turn = (_phase(scene, dt_s) - _phase(scene, 0.0) + math.pi) % (2 * math.pi) - math.pi
    return turn / K / dt_s


DIRECTIONAL = {"type": "directional", "irradiance": {"type": "rgb", "value": 3.0}}


@pytest.mark.parametrize("travel, far_sphere, rate", [
    ((0.0, 0.0, 1.0), False, -2 * SPEED_M_S),  # light along the view: both legs shorten at v
    ((0.0, -0.6, 0.8), False, -SPEED_M_S - 0.8 * SPEED_M_S),  # the light leg at v·ω_z
    ((0.0, -0.6, 0.8), True, -SPEED_M_S - 0.8 * SPEED_M_S),  # whatever else the scene holds
])  # fmt: skip
def test_a_plane_moving_into_a_directional_lights_wave(travel, far_sphere, rate):
    extra = {"far": {"type": "sphere", "center": [50.0, 0.0, 0.0], "radius": 0.01}} if far_sphere else {}
    scene = _scene({**DIRECTIONAL, "direction": list(travel)}, **extra)
    assert _length_rate_m_s(scene) == pytest.approx(rate, abs=0.05)


def test_a_point_light_at_the_camera_still_gives_both_legs():
    assert _length_rate_m_s(_scene({"type": "point", "position": [0, 0, 0], "intensity": {"type": "rgb", "value": 5.0}})) == pytest.approx(-20.0, abs=0.05)


@pytest.mark.parametrize("correlation", ["replay", "reconnection"])  # the single and the paired tracer
def test_a_constant_environment_gives_the_plane_wave_phase_by_either_sampling(correlation):
    """A static plane whose centre pixel sees x = (0, 0, 2), 3 m from the centre c of the
    scene's bounding sphere (radius R): direction ω's light travels R − ω·(x − c) =
    R + 3 ω_x to x, then 2 m to the camera. The phase is arg ∫ cos θ e^{ik(2 + R + 3ω_x)} dω
    over the hemisphere the plane faces; emitter samples and escaped rays both enter it."""
    scene = _scene({"type": "constant"}, speed=0.0, plane_at=(3.0, 0.0, 2.0), resolution=1, fov=2.0)
    radius = math.hypot(5.0, 5.0)  # the 10 m × 10 m plane's bounding sphere
    theta, phi = np.meshgrid(np.linspace(0, math.pi / 2, 801), np.linspace(0, 2 * math.pi, 1601), indexing="ij")
    omega_x = np.sin(theta) * np.cos(phi)
    integrand = np.cos(theta) * np.sin(theta) * np.exp(1j * K * (2.0 + radius + 3.0 * omega_x))
    expected = np.angle(np.trapezoid(np.trapezoid(integrand, phi[0], axis=1), theta[:, 0]))
    got = _phase(scene, 0.0, spp=4096, correlation=correlation)
    assert abs((got - expected + math.pi) % (2 * math.pi) - math.pi) < 0.02, (got, expected)
