"""Pictures of the scenarios (``scenarios.render``): the carrier and its IMU are seen
(segmentation renders: each key geom covers pixels), frames are not blank and follow the
motion, ``aligngym render`` writes a readable video, and bad options are one-line
errors."""
import shutil
import weakref

import numpy as np
import pytest

from aligngym.scenarios.config import ConfigError, load_scenario
from aligngym.scenarios.render import SceneRenderer

SIZE = (240, 320)


def scene(frame: np.ndarray) -> np.ndarray:
    """The part of a frame that is neither the overlay's band nor the close-up's inset."""
    return frame[frame.shape[0] // 4: frame.shape[0] * 3 // 5]


PICTURES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Each renderer's segmentation pictures by (time, close-up): the geoms of one picture are
counted by several tests (a picture is drawn once)."""


def pixels(renderer: SceneRenderer, t: float, prefix: str, close_up: bool = False) -> int:
    """Pixels showing the geoms whose names start with prefix."""
    model = renderer.model
    ids = [i for i in range(model.ngeom) if model.geom(i).name.startswith(prefix)]
    assert ids, prefix
    drawn = PICTURES.setdefault(renderer, {})
    if (t, close_up) not in drawn:
        drawn[t, close_up] = renderer.segmentation(t, close_up)
    return int(np.isin(drawn[t, close_up], ids).sum())


@pytest.fixture(scope="module")
def ship():
    renderer = SceneRenderer(load_scenario("ship-sway-rotary").with_options(duration=20.0),
                             seed=1, size=SIZE)
    yield renderer
    renderer.close()


@pytest.mark.parametrize("prefix, least_wide, least_close", [
    ("hull", 800, None), ("bridge", 500, None), ("gimbal_outer_frame", 5, 200),
    ("gimbal_inner_frame", 3, 150), ("imu_case", 5, 150), ("imu_axis_", 1, 30)])
def test_the_ship_its_gimbal_frames_and_the_imu_are_seen(ship, prefix, least_wide,
                                                          least_close):
    """In the follow camera's picture the hull and the bridge fill much of the frame and
    the gimbal shows; in the close-up each gimbal frame, the IMU case and its axes cover
    pixels (measured at 320x240 over four times: hull 1500-3300, bridge 1300-1450, the
    close-up's outer frame 390-590, inner frame 285-345, IMU case 275-450, axes 63-197)."""
    for t in (3.0, 11.0):          # two attitudes of the sway and of the gimbal
        assert pixels(ship, t, prefix) >= least_wide
        if least_close is not None:
            assert pixels(ship, t, prefix, close_up=True) >= least_close


def test_frames_are_not_blank_and_follow_the_motion(ship):
    """The sway moves the hull and the gimbal turns: the close-up differs between two
    times by much more than the overlay does, and a frame has contrast."""
    a, b = ship.frame(3.0), ship.frame(4.0)
    assert a.shape == SIZE + (3,) and a.dtype == np.uint8
    assert scene(a).std() > 20
    h, w = SIZE[0] // 3, SIZE[1] // 3
    inset_a, inset_b = a[-h:, -w:].astype(int), b[-h:, -w:].astype(int)
    assert (np.abs(inset_a - inset_b).sum(-1) > 30).mean() > 0.05
    # the gimbal turns relative to the hull: the outer frame's pixels move
    first = ship.segmentation(3.0, close_up=True)
    second = ship.segmentation(4.0, close_up=True)
    outer = [i for i in range(ship.model.ngeom)
             if ship.model.geom(i).name.startswith("gimbal_outer_frame")]
    assert (np.isin(first, outer) != np.isin(second, outer)).sum() > 100


def wave_boat_config():
    return load_scenario("usv-mems-waves").with_options(duration=10.0)


@pytest.fixture(scope="module")
def wave_boat():
    """The floating boat's pictures of one episode (10 s of usv-mems-waves, seed 3): its
    dressed run is simulated once for the three tests that pose it."""
    renderer = SceneRenderer(wave_boat_config(), seed=3, size=SIZE)
    yield renderer
    renderer.close()


@pytest.mark.parametrize("name", ["usv-mems-swing", "usv-mems-waves", "static-large-azimuth",
                                  "figure8-gps"])
def test_other_worlds_show_the_carrier_and_the_imu(name, request):
    """The small boat (prescribed, and floating in its sea: posed from its own run), the
    marble platform and the car (its run; the close-up shows the instruments inside the
    body): the carrier and the IMU case are seen."""
    if name == "usv-mems-waves":
        renderer = request.getfixturevalue("wave_boat")
    else:
        config = load_scenario(name).with_options(duration=10.0)
        renderer = SceneRenderer(config, seed=2, size=SIZE)
    try:
        carrier = {"usv-mems-swing": "hull", "usv-mems-waves": "hull",
                   "static-large-azimuth": "slab", "figure8-gps": "cabin"}[name]
        assert pixels(renderer, 6.0, carrier) > 1000
        assert pixels(renderer, 6.0, "imu_case", close_up=True) > 100
        assert scene(renderer.frame(6.0)).std() > 20
    finally:
        if name != "usv-mems-waves":
            renderer.close()


def test_the_wave_boat_is_posed_from_its_episode(wave_boat):
    """The floating boat's pose is the episode's: its run with the same seed (the same
    sea), the carrier's attitude read back from MuJoCo equal to the simulated truth."""
    from aligngym.models.attitude import dcm_to_quat, quat_angle
    from aligngym.scenarios.simulate import simulate
    renderer = wave_boat
    episode = simulate(wave_boat_config(), seed=3, ideal=True)
    k = 600                                       # 6 s at 100 Hz
    renderer.pose(float(episode.truth.t[k]))
    C_b_t = renderer.data.xmat[renderer.model.body("carrier").id].reshape(3, 3)
    # the truth's q_b_n is in ENU at the IMU; the plane t is ENU at the origin: the
    # two differ by the meridian convergence over metres (< 1e-6 rad)
    assert quat_angle(dcm_to_quat(C_b_t), episode.truth.q_b_n[k]) < 1e-5


VIDEO = ["render", "static-large-azimuth", "--duration", "1", "--fps", "4", "--size",
         "96x128"]


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    """``aligngym render``'s video of 1 s at 4 fps, 96 x 128 pixels, alone in its
    directory (nothing else left), written once: read back below, and the good video an
    interrupted render must leave as it was."""
    from aligngym.scenarios.cli import main
    folder = tmp_path_factory.mktemp("video")
    out = folder / "v.mp4"
    assert main([*VIDEO, "--out", str(out)]) == 0
    assert [p.name for p in folder.iterdir()] == ["v.mp4"]
    return out


@pytest.mark.filterwarnings("ignore:unclosed file <_io.Buffered:ResourceWarning",
                            "ignore::pytest.PytestUnraisableExceptionWarning")
def test_render_writes_a_video(tmp_path, video):
    """(Reading the video back, imageio-ffmpeg's frame reader leaves its ffmpeg process's
    pipes to the garbage collector, closed or not: the two warnings allowed here are
    that library's, in this test alone.)"""
    from aligngym.scenarios.cli import main
    import imageio.v2 as imageio
    with imageio.get_reader(video) as reader:
        frames = list(iter(reader))      # its len() is inf: no list() size hint
    assert len(frames) == 5 and frames[0].shape == (96, 128, 3)
    png = tmp_path / "frame.png"
    assert main(["render", "static-large-azimuth", "--start", "0.5", "--duration", "1",
                 "--size", "96x128", "--out", str(png)]) == 0
    image = imageio.imread(png)
    assert image.shape == (96, 128, 3) and scene(image).std() > 20


def test_an_interrupted_render_leaves_the_old_video(tmp_path, monkeypatch, capsys, video):
    """Ctrl-C after three frames: the good video that was there is untouched (the new
    one was written under a temporary name), nothing else is left, one line, exit 130."""
    from aligngym.scenarios import render
    from aligngym.scenarios.cli import main
    out = tmp_path / "v.mp4"
    shutil.copyfile(video, out)               # the good video (``aligngym render``'s own)
    before = out.read_bytes()
    frame, count = render.SceneRenderer.frame, []

    def interrupted(self, *args, **kwargs):
        count.append(1)
        if len(count) > 3:
            raise KeyboardInterrupt
        return frame(self, *args, **kwargs)

    monkeypatch.setattr(render.SceneRenderer, "frame", interrupted)
    capsys.readouterr()
    assert main([*VIDEO, "--duration", "4", "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip().splitlines() == [
        "aligngym: interrupted; no output was written (an existing one is unchanged)"]
    assert out.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["v.mp4"]


@pytest.mark.parametrize("argv, message", [
    (["--fps", "500"], "--fps = 500 is out of range"),
    (["--size", "big"], "--size must be HxW"),
    (["--size", "4x4"], "render size = 4x4 is out of range"),
    (["--out", "x.avi"], "the video is written as .mp4"),
])
def test_bad_render_options_are_one_line_errors(tmp_path, capsys, argv, message):
    from aligngym.scenarios.cli import main
    args = ["render", "static-large-azimuth", "--duration", "1",
            "--out", str(tmp_path / "v.mp4"), *argv]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_an_estimator_needs_a_pipeline(tmp_path):
    """--estimator runs the experiment the scenario file names (any file:
    tests/test_own_scenario.py); a file that names none, or a configuration that is not
    its file's, is a one-line error before any work."""
    from dataclasses import replace

    from aligngym.scenarios.video import render_video
    from aligngym.scenarios.registry import DATA_DIR
    path = tmp_path / "mine.toml"
    text = (DATA_DIR / "ship-sway-rotary.toml").read_text()
    path.write_text(text.replace('experiment = "paper003"', "# no experiment"))
    config = load_scenario(str(path)).with_options(duration=1.0)
    with pytest.raises(ConfigError, match="--estimator needs a scenario that names an "
                       "experiment"):
        render_video(config, str(tmp_path / "v.mp4"), estimator="kf")
    path.write_text(text)
    config = replace(load_scenario(str(path)).with_options(duration=1.0), latitude=0.7)
    with pytest.raises(ConfigError, match="this configuration differs from it"):
        render_video(config, str(tmp_path / "v.mp4"), estimator="kf")


def test_the_car_is_posed_with_every_joint():
    """The car's picture at a time carries that step's steering and suspension, not the
    run's last (parked at 0 s: wheels straight and the suspension at its settled rest)."""
    config = load_scenario("ring-road-odometer").with_options(duration=30.0)
    renderer = SceneRenderer(config, seed=0, size=SIZE)
    try:
        steer = [renderer.model.joint(f"{w}_steer").qposadr[0] for w in ("fl", "fr")]
        renderer.pose(0.0)
        at_rest = renderer.data.qpos[steer].copy()
        renderer.pose(29.0)                      # on the ring: the front wheels steered
        turning = renderer.data.qpos[steer].copy()
        assert np.abs(at_rest).max() < 1e-3 < np.abs(turning).min()
    finally:
        renderer.close()


def test_the_sea_is_the_wave_model(wave_boat):
    """The wave-driven ship's heightfield at a time is the sea of its episode: MuJoCo's
    surface (a ray cast straight down) against the wave model's elevation there."""
    import mujoco
    renderer = wave_boat
    renderer.pose(7.0)
    model, data = renderer.model, renderer.data
    sea = model.geom("sea_waves").id
    geomgroup = np.array([0, 1, 0, 0, 0, 0], np.uint8)
    for x, y in ((-30.0, 12.0), (25.0, -40.0), (40.0, 35.0)):
        hit = np.zeros(1, np.int32)
        top = 50.0
        distance = mujoco.mj_ray(model, data, np.array([x, y, top]),
                                 np.array([0.0, 0.0, -1.0]), geomgroup, 1, -1, hit)
        assert hit[0] == sea
        expected = renderer.world.sea_surface(7.0, np.array([x]), np.array([y]))[0]
        assert abs((top - distance) - expected) < 0.05     # the 0.4 m grid's chord


def test_render_start_and_output_errors(tmp_path, capsys):
    from aligngym.scenarios.cli import main
    blocked = tmp_path / "file"
    blocked.write_text("")
    for argv, message in (
            (["--out", str(blocked / "v.mp4")], "--out"),
            (["--estimator", "nokf", "--out", str(tmp_path / "v.mp4")], "--estimator"),):
        assert main(["render", "static-large-azimuth", "--duration", "1", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and "\n" not in err
