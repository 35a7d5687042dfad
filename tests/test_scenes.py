"""The rendered scenes are recognisable (issue 15): the key geoms of the car world and the
marble platform show up in a segmentation render, the RGB frame is not blank, and the
scene dressing is visual only."""
from dataclasses import replace

from aligngym import models  # noqa: F401  (first: headless MUJOCO_GL=egl before mujoco loads)
import mujoco
import numpy as np
import pytest

from aligngym.models.car import CarParams, CarWorld, car_mjcf
from aligngym.scenarios.config import load_scenario
from aligngym.scenarios.worlds import make_world

MIN_PIXELS = 20
"""Least pixels a key geom covers in a 240 x 320 frame (the smallest measured: 50, an
IMU axis)."""


RENDERERS: dict[int, mujoco.Renderer] = {}
"""One renderer (GL context) per world of this module, made at its first picture and
closed with the world's fixture: a context costs 0.3-0.4 s to make (the model's upload),
more than an RGB picture of it."""


def _closed_after(world):
    yield world
    renderer = RENDERERS.pop(id(world), None)
    if renderer is not None:
        renderer.close()


@pytest.fixture(scope="module", params=["ring-road-odometer", "figure8-gps"])
def car_world(request):
    motion = load_scenario(request.param).motion
    yield from _closed_after(CarWorld(motion.car_params(), motion.make_track(),
                                      motion.profile(), pictures=True))


@pytest.fixture(scope="module")
def platform_world():
    world = make_world(load_scenario("static-large-azimuth"), np.random.default_rng(0))
    world.data.qpos[:] = world.joint_state(np.zeros(1))[0][0]
    yield from _closed_after(world)


def render(world, distance, elevation, azimuth, groups=None, segmentation=False):
    """A 240 x 320 frame looking at the carrier: RGB, or (geom id, object type) pixels."""
    model, data = world.model, world.data
    mujoco.mj_forward(model, data)
    camera = mujoco.MjvCamera()
    camera.distance, camera.elevation, camera.azimuth = distance, elevation, azimuth
    camera.lookat[:] = data.xpos[model.body("carrier").id]
    option = mujoco.MjvOption()
    if groups is not None:
        option.geomgroup[:] = 0
        option.geomgroup[list(groups)] = 1
    renderer = RENDERERS.get(id(world))
    if renderer is None:
        renderer = RENDERERS[id(world)] = mujoco.Renderer(model, 240, 320)
    if segmentation:
        renderer.enable_segmentation_rendering()
    try:
        renderer.update_scene(data, camera, option)
        return renderer.render().copy()
    finally:
        renderer.disable_segmentation_rendering()


def geom_pixels(world, seg, prefix: str) -> int:
    """Pixels of the geoms whose names start with prefix."""
    model = world.model
    ids = [i for i in range(model.ngeom) if model.geom(i).name.startswith(prefix)]
    assert ids, f"no geom named {prefix}*"
    is_geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)    # an int: a NumPy comparison
    return int(np.isin(seg[..., 0], ids)[is_geom].sum())


def test_car_body_and_track_are_seen(car_world):
    seg = render(car_world, 9.0, -20.0, 130.0, segmentation=True)
    for name in ("chassis", "cabin", "rear_window", "window_", "bumper_", "track_path",
                 "track_edge", "track_road"):
        assert geom_pixels(car_world, seg, name) >= MIN_PIXELS, name
    rgb = render(car_world, 9.0, -20.0, 130.0)
    assert rgb.shape == (240, 320, 3) and rgb.std() > 20.0


def test_car_instruments_are_seen_in_the_xray_view(car_world):
    """The IMU sits inside the body: hiding groups 0 and 1 (physics geoms, dressing)
    leaves the instruments (group 2)."""
    seg = render(car_world, 3.0, -30.0, 225.0, groups=[2], segmentation=True)
    for name in ("imu_case", "imu_axis_x", "imu_axis_y", "imu_axis_z", "antenna"):
        assert geom_pixels(car_world, seg, name) >= MIN_PIXELS, name
    assert geom_pixels(car_world, seg, "chassis") == 0


def test_platform_slab_imu_and_axes_are_seen(platform_world):
    seg = render(platform_world, 2.5, -30.0, -105.0, segmentation=True)
    for name in ("slab", "imu_case", "imu_axis_x", "imu_axis_y", "imu_axis_z", "pier"):
        assert geom_pixels(platform_world, seg, name) >= MIN_PIXELS, name
    assert render(platform_world, 2.5, -30.0, -105.0).std() > 20.0


def test_dressing_is_visual_only(car_world, platform_world):
    """Every geom of the dressing (groups 1, 2) is contact-free, and the bodies weigh what
    their physics geoms do."""
    for world in (car_world, platform_world):
        m = world.model
        dressing = np.isin(m.geom_group, [1, 2])
        assert dressing.sum() > 5
        assert not m.geom_contype[dressing].any() and not m.geom_conaffinity[dressing].any()
    p = CarParams()
    m = car_world.model
    assert m.body("carrier").mass[0] == p.chassis_mass
    assert m.body("fl_wheel").mass[0] == p.wheel_mass
    np.testing.assert_allclose(   # the chassis box's, 0.85 x 2.2 x 0.3 m half sizes
        m.body("carrier").inertia, p.chassis_mass / 3 * np.array(
            [2.2 ** 2 + 0.3 ** 2, 0.85 ** 2 + 0.3 ** 2, 0.85 ** 2 + 2.2 ** 2]), rtol=1e-14)
    assert platform_world.model.body("carrier").mass[0] == 578.0


def test_gimbal_frames_drawn_only_with_a_gimbal():
    def names(params):
        model = mujoco.MjModel.from_xml_string(car_mjcf(params, extent=50.0)[0])
        return {model.geom(i).name for i in range(model.ngeom)}

    assert {"gimbal_outer", "gimbal_inner"} <= names(CarParams(gimbal=True))
    assert "gimbal_outer" not in names(CarParams())
    motion = load_scenario("ring-road-odometer").motion
    assert replace(motion, gimbal_outer_rate=0.1).car_params().gimbal


@pytest.mark.parametrize("roughness", [0.0, 0.004])
def test_the_undressed_car_drives_bit_for_bit_like_the_dressed_one(roughness):
    """The simulation's model leaves the dressing out (pictures=False): the same motion,
    every step, on a plane and on a rough road."""
    motion = replace(load_scenario("ring-road-odometer").motion, start_time=0.5,
                     roughness_rms=roughness)
    worlds = [CarWorld(motion.car_params(), motion.make_track(), motion.profile(),
                       roughness_seed=3, pictures=pictures) for pictures in (False, True)]
    bare, dressed = (world.model.ngeom for world in worlds)
    assert bare < dressed / 3
    runs = [world.run(3.0) for world in worlds]
    np.testing.assert_array_equal(runs[0].qpos, runs[1].qpos)
    np.testing.assert_array_equal(runs[0].omega, runs[1].omega)
    np.testing.assert_array_equal(runs[0].vel, runs[1].vel)
