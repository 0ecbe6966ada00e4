"""The cameras' renderer on known scenes (pybullet DIRECT, no master): the lander posed as the
model says, the depth buffer on the true ground, the lander in view, what the sun, its shadows,
the lights and the exposure do to the picture."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ow_cameras.config import CameraConfig
from ow_cameras.render import Lighting, SceneRenderer, View, expose
from ow_cameras.rig import PANEL_LINK, Pinhole, RigPose
from ow_description.description import STOWED
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap

#: Small images: the behaviour is the same at any size, and they render fast.
PINHOLE = Pinhole(320, 240, math.radians(21.0))
GROUND_Z = -0.155
#: Looking back over the lander's +y side at bare ground 1.6 to 2.3 m away.
GROUND_VIEW = {"j_ant_pan": 3.1, "j_ant_tilt": 0.9}
CONFIG = CameraConfig()


def flat(z: float = GROUND_Z) -> HeightMap:
    return HeightMap.flat(z, half_extent=4.0, resolution=0.1)


def lighting(
    intensities: tuple[float, float] = (0.0, 0.0),
    sun: tuple[float, float] | None = (150.0, 30.0),
    ambient: float = 1.0,
    cone: float = CONFIG.lights.cone_angle_rad,
) -> Lighting:
    """The configured light; ``sun`` (azimuth, elevation) deg or None: night."""
    config = CONFIG.sun
    if sun is not None:
        config = replace(config, azimuth_deg=sun[0], elevation_deg=sun[1])
    return Lighting(
        sun_direction=config.direction,
        sun_irradiance_w_m2=config.irradiance_w_m2 if sun is not None else 0.0,
        ambient_w_m2=ambient,
        light_irradiance_at_1m_w_m2=CONFIG.lights.irradiance_at_1m_w_m2,
        cone_angle_rad=cone,
        intensities={"left": intensities[0], "right": intensities[1]},
    )


@pytest.fixture(scope="module")
def renderer():
    with SceneRenderer() as scene:
        yield scene


def look(renderer: SceneRenderer, joints: dict, terrain: HeightMap, light: Lighting):
    """(the left camera's View, its (4, 4) pose in base_link)."""
    renderer.set_terrain(terrain)
    renderer.set_joints({**STOWED, **joints})
    rig = RigPose.from_panel(renderer.X_base_link(PANEL_LINK))
    (view,) = renderer.render(PINHOLE, [rig.X_base_left], light, rig.lights)
    return view, rig.X_base_left


def points_of(view: View, X: np.ndarray) -> np.ndarray:
    """(h, w, 3) m, base_link, of each pixel's depth (inf where the sky is)."""
    x, y = PINHOLE.rays()
    z = view.depth_m.astype(float)
    optical = np.stack([x * z, y * z, z], axis=2)
    return optical @ X[:3, :3].T + X[:3, 3]


def test_the_lander_is_posed_as_the_model_says(renderer):
    model = LanderModel()
    for joints in (
        {"j_ant_pan": 0.0, "j_ant_tilt": 0.0},
        {"j_ant_pan": 1.2, "j_ant_tilt": -0.4},
        {"j_ant_pan": -2.5, "j_ant_tilt": 1.1},
    ):
        renderer.set_joints({**STOWED, **joints})
        expected = model.fk(model.q_from({**STOWED, **joints}), PANEL_LINK)
        assert np.allclose(renderer.X_base_link(PANEL_LINK), expected, atol=1e-6)


def test_the_depth_buffer_puts_the_ground_where_it_is(renderer):
    view, X = look(renderer, GROUND_VIEW, flat(), lighting())
    assert np.isfinite(view.depth_m).all()  # nothing but ground in view
    # Each pixel's ray, by the pinhole model the CameraInfo publishes, meets the plane at:
    x, y = PINHOLE.rays()
    rays = np.stack([x, y, np.ones_like(x)], axis=2) @ X[:3, :3].T
    depth_true = (GROUND_Z - X[2, 3]) / rays[:, :, 2]
    error = view.depth_m - depth_true
    assert np.median(np.abs(error)) < 0.001
    assert np.percentile(np.abs(error), 99) < 0.005


def test_the_lander_is_in_view_looking_down_from_the_mast(renderer):
    view, X = look(renderer, {"j_ant_pan": 0.0, "j_ant_tilt": 1.3}, flat(), lighting())
    points = points_of(view, X)
    above = np.isfinite(view.depth_m) & (points[:, :, 2] > GROUND_Z + 0.1)
    assert above.mean() > 0.5  # the deck, well above the ground
    lit = view.irradiance[above].sum(axis=1)
    assert np.median(lit) > 0.0


def test_without_sun_or_lights_the_picture_is_black(renderer):
    view, _ = look(renderer, GROUND_VIEW, flat(), lighting(sun=None, ambient=0.0))
    assert not view.irradiance.any()


def test_the_lights_add_up_and_scale_with_intensity(renderer):
    night = {"sun": None, "ambient": 0.0}
    left, _ = look(renderer, GROUND_VIEW, flat(), lighting((1.0, 0.0), **night))
    right, _ = look(renderer, GROUND_VIEW, flat(), lighting((0.0, 1.0), **night))
    both, _ = look(renderer, GROUND_VIEW, flat(), lighting((1.0, 1.0), **night))
    half, _ = look(renderer, GROUND_VIEW, flat(), lighting((0.5, 0.5), **night))
    assert np.allclose(both.irradiance, left.irradiance + right.irradiance, rtol=1e-5, atol=1e-6)
    assert np.allclose(half.irradiance * 2.0, both.irradiance, rtol=1e-5, atol=1e-6)
    assert (both.irradiance > 0.0).mean() > 0.99  # the cone (70 deg) holds the whole view
    # The lights turn with the cameras: the left one lights the image's left half more.
    width = PINHOLE.width
    assert left.irradiance[:, : width // 2].mean() > left.irradiance[:, width // 2 :].mean()
    assert right.irradiance[:, width // 2 :].mean() > right.irradiance[:, : width // 2].mean()


def test_the_lights_fall_off_with_distance_as_oceanwaters(renderer):
    view, X = look(renderer, GROUND_VIEW, flat(), lighting((1.0, 1.0), sun=None, ambient=0.0))
    points = points_of(view, X)
    renderer.set_joints({**STOWED, **GROUND_VIEW})
    rig = RigPose.from_panel(renderer.X_base_link(PANEL_LINK))
    expected = np.zeros(points.shape[:2])
    for light in rig.lights:
        to_light = light.position - points
        d2 = (to_light**2).sum(axis=2)
        cos = np.maximum(to_light[:, :, 2] / np.sqrt(d2), 0.0)  # the ground's normal is +z
        expected += 25.0 * cos / d2
    # irradiance = albedo x expected: the ratio is the ground's albedo, whatever the distance.
    albedo = view.irradiance.mean(axis=2) / expected
    near, far = albedo[-40:].mean(), albedo[:40].mean()
    assert near == pytest.approx(far, rel=0.05)
    assert 0.5 < np.median(albedo) < 0.85  # the regolith's mean albedo, 0.72 x tint


def test_outside_the_cone_the_lights_give_nothing(renderer):
    view, X = look(
        renderer, GROUND_VIEW, flat(), lighting((1.0, 0.0), sun=None, ambient=0.0, cone=0.08)
    )
    points = points_of(view, X)
    renderer.set_joints({**STOWED, **GROUND_VIEW})
    light = RigPose.from_panel(renderer.X_base_link(PANEL_LINK)).lights[0]
    to_point = points - light.position
    angle = np.arccos(np.clip((to_point @ light.axis) / np.linalg.norm(to_point, axis=2), -1, 1))
    lit = view.irradiance.sum(axis=2) > 0.0
    assert lit.any() and not lit.all()
    assert angle[lit].max() <= 0.04 + 1e-3  # half the cone
    assert angle[~lit].min() >= 0.04 - 1e-3


def test_a_wall_casts_a_shadow_as_long_as_the_sun_says(renderer):
    # Ground beside the lander (-x) with a 0.2 m wall along x at y 0.95-1.0, the sun from +y
    # 30 deg up: the wall's shadow covers y 0.60-0.95 of the ground in view (y 0.3-1.0).
    terrain = HeightMap.flat(GROUND_Z, half_extent=4.0, resolution=0.02)
    xs, ys = terrain.cell_centres()
    heights = terrain.heights.copy()
    heights[np.ix_((ys >= 0.95) & (ys <= 1.0), xs <= -0.9)] += 0.2
    terrain = HeightMap(heights, terrain.resolution, terrain.origin_x, terrain.origin_y)
    joints = {"j_ant_pan": -math.pi / 2, "j_ant_tilt": 0.8}
    view, X = look(renderer, joints, terrain, lighting(sun=(90.0, 30.0)))
    points = points_of(view, X)
    ground = np.isfinite(view.depth_m) & (np.abs(points[:, :, 2] - GROUND_Z) < 0.01)
    grey = view.irradiance.mean(axis=2)
    shadowed = ground & (points[:, :, 1] > 0.68) & (points[:, :, 1] < 0.88)
    sunlit = ground & (points[:, :, 1] > 0.30) & (points[:, :, 1] < 0.52)
    assert shadowed.sum() > 1000 and sunlit.sum() > 1000
    # In the shadow only the sky's 1 W/m^2; in the sun 25 W/m^2 more (50 sin 30 deg).
    ratio = np.median(grey[shadowed]) / np.median(grey[sunlit])
    assert ratio == pytest.approx(1.0 / 26.0, rel=0.3)


def test_the_exposure_scales_the_brightness_until_it_saturates(renderer):
    view, _ = look(renderer, GROUND_VIEW, flat(), lighting((1.0, 1.0)))
    short = expose(view.irradiance, 0.0005, CONFIG.saturation_j_m2).astype(float)
    long = expose(view.irradiance, 0.001, CONFIG.saturation_j_m2).astype(float)
    unsaturated = (long < 250) & (short > 20)
    assert unsaturated.mean() > 0.9
    assert np.median(long[unsaturated] / short[unsaturated]) == pytest.approx(2.0, rel=0.02)
    assert np.abs(long[unsaturated] - 2 * short[unsaturated]).max() <= 1.0  # rounding only
    saturated = expose(view.irradiance, 0.05, CONFIG.saturation_j_m2)
    assert (saturated == 255).mean() > 0.99
