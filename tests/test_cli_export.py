"""The aligngym command line: data export format, reproducibility, and bad input."""
import subprocess
import sys

import numpy as np
import pytest

from aligngym.scenarios.cli import main

REQUIRED = {"t": 1, "lat": 1, "lon": 1, "h": 1, "v_n": 2, "q_b_n": 2, "q_s_n": 2,
            "gimbal_angles": 2, "imu_t": 1, "dtheta": 2, "dv": 2}


def run_cli(*args):
    """Run the installed entry point as a user would; returns (code, stdout, stderr)."""
    proc = subprocess.run([sys.executable, "-m", "aligngym.scenarios.cli", *args], capture_output=True,
                          text=True)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim")
    paths = {}
    for name, extra in {"a": [], "b": [], "ideal": ["--ideal"], "other": ["--seed", "8"]}.items():
        seed = [] if extra[:1] == ["--seed"] else ["--seed", "7"]
        out = d / f"{name}.npz"
        assert main(["simulate", "ship-sway-rotary", "--duration", "20", *seed, *extra,
                     "--out", str(out)]) == 0
        paths[name] = out
    return {k: dict(np.load(v)) for k, v in paths.items()}


def test_export_arrays_and_units(files):
    f = files["a"]
    for key, ndim in REQUIRED.items():
        assert f[key].ndim == ndim, key
    N, M = f["t"].size, f["imu_t"].size
    assert (N, M) == (2001, 2000)
    assert f["v_n"].shape == (N, 3) and f["q_s_n"].shape == (N, 4)
    assert f["dtheta"].shape == (M, 3) and f["gimbal_angles"].shape == (N, 2)
    # Every IMU interval ends at a truth time and the first starts at one.
    np.testing.assert_array_equal(f["imu_t"], f["t"][1:])
    assert f["t"][0] == 0.0
    np.testing.assert_allclose(np.linalg.norm(f["q_b_n"], axis=1), 1.0, atol=1e-14)
    assert np.rad2deg(f["lat"]).mean() == pytest.approx(40.0, abs=1e-3)
    assert np.rad2deg(f["lon"]).mean() == pytest.approx(118.0, abs=1e-3)


def test_velocity_increments_integrate_to_the_truth_with_normal_gravity(files):
    """dv is m/s in the sensor frame: turned to n (attitude at each interval's start,
    rotated by half its dtheta) and summed with the model's normal gravity and the
    Coriolis and transport terms over the ideal file's 20 s, it is the truth's velocity
    change to 0.5 mm/s (measured 0.23 mm/s; a hard-coded 9.8 m/s^2 would be 32 mm/s off,
    the Coriolis term alone is 0.6 mm/s)."""
    from aligngym.models.attitude import quat_to_dcm
    from aligngym.models.earth import earth_rate_n, gravity_n, transport_rate_n
    f = files["ideal"]
    dv_b = f["dv"] + 0.5 * np.cross(f["dtheta"], f["dv"])
    dv_n = np.einsum("kij,kj->ki", quat_to_dcm(f["q_s_n"][:-1]), dv_b)
    mid = lambda x: 0.5 * (x[1:] + x[:-1])  # noqa: E731
    lat, h, v = mid(f["lat"]), mid(f["h"]), mid(f["v_n"])
    w = 2 * earth_rate_n(lat) + transport_rate_n(lat, h, v)
    dt = np.diff(f["t"])[:, None]
    predicted = dv_n.sum(0) + ((gravity_n(lat, h) - np.cross(w, v)) * dt).sum(0)
    np.testing.assert_allclose(predicted, f["v_n"][-1] - f["v_n"][0], atol=0.5e-3)


def test_same_seed_same_file_and_ideal_shares_truth(files):
    for key in files["a"]:
        np.testing.assert_array_equal(files["a"][key], files["b"][key])
    truth_keys = ["t", "lat", "lon", "h", "v_n", "q_b_n", "q_s_n", "gimbal_angles"]
    for key in truth_keys:
        np.testing.assert_array_equal(files["a"][key], files["ideal"][key])
    assert not np.array_equal(files["a"]["dtheta"], files["ideal"]["dtheta"])
    assert "gyro_bias" in files["a"] and "gyro_bias" not in files["ideal"]
    # Another seed draws other sway phases: another truth.
    assert not np.array_equal(files["a"]["h"], files["other"]["h"])


def test_errors_on_the_file_match_the_drawn_biases(files):
    err = (files["a"]["dtheta"] - files["ideal"]["dtheta"]) / 0.01
    np.testing.assert_allclose(err.mean(0), files["a"]["gyro_bias"], atol=3e-9)


@pytest.mark.parametrize("args, expected", [
    (["simulate", "no-such-scenario", "--out", "x.npz"],
     "valid choices: figure8-gps, figure8-gps-changing, figure8-gps-paper, "
     "ring-road-odometer, ship-sway-rotary, ship-sway-rotary-changing, "
     "ship-sway-rotary-paper, ship-waves-rotary, static-large-azimuth"),
    (["simulate", "ship-sway-rotary", "--duration", "-5", "--out", "x.npz"], "--duration"),
    (["simulate", "ship-sway-rotary", "--imu-rate", "0", "--out", "x.npz"], "--imu-rate"),
    (["simulate", "ship-sway-rotary", "--imu-rate", "5000", "--out", "x.npz"],
     "--imu-rate = 5000 Hz is out of range"),
    (["simulate", "ship-sway-rotary", "--duration", "0.015", "--out", "x.npz"], "--duration = 0.015 s"),
    (["simulate", "ship-sway-rotary", "--seed", "-1", "--out", "x.npz"], "--seed"),
    (["simulate", "ship-sway-rotary", "--duration", "1", "--out", "x.csv"], ".npz"),
    (["simulate", "ship-sway-rotary"], "--out"),
    (["bogus"], "invalid choice"),
])
def test_bad_input_one_line_error(args, expected):
    code, out, err = run_cli(*args)
    assert code != 0
    assert expected in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err


def test_bad_scenario_file_names_field(tmp_path):
    from aligngym.scenarios.config import DATA_DIR
    text = (DATA_DIR / "ship-sway-rotary.toml").read_text().replace(
        "latitude_deg = 40.0", "latitude_deg = 95.0")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code, _, err = run_cli("simulate", str(path), "--out", str(tmp_path / "x.npz"))
    assert code == 2 and "origin.latitude_deg = 95 deg is out of range [-89, 89]" in err


def test_imu_rate_option_changes_sample_count(tmp_path):
    out = tmp_path / "r.npz"
    assert main(["simulate", "ship-sway-rotary", "--duration", "2", "--imu-rate", "200",
                 "--out", str(out)]) == 0
    f = np.load(out)
    assert f["imu_t"].size == 400 and f["t"].size == 401


def test_cli_module_loads_no_physics_or_estimators():
    """Help, version and option errors answer without MuJoCo, SciPy, numba or the
    estimators (imports stay inside the commands)."""
    heavy = ("mujoco", "scipy", "numba", "matplotlib", "aligngym.estimators",
             "aligngym.models")
    code = ("import sys, aligngym.scenarios.cli; "
            f"print(sorted(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_scenarios_and_experiments_load_no_physics():
    """Reading every shipped scenario file and importing every experiment (what bench's
    option checks need) loads no MuJoCo, SciPy or Numba: those load when a world is
    built, a spline fitted or the strapdown run, so scenario and option errors answer at
    once; ``import aligngym`` registers the gymnasium ids."""
    heavy = ("mujoco", "scipy", "numba", "matplotlib")
    code = ("import sys, gymnasium, aligngym; "
            "from aligngym.scenarios.config import load_scenario; "
            "from aligngym.scenarios.registry import experiment_names, scenario_names; "
            "from aligngym.scenarios.experiments import experiment_class; "
            "[load_scenario(n) for n in scenario_names()]; "
            "[experiment_class(n) for n in experiment_names()]; "
            "assert 'aligngym/Alignment-v1' in gymnasium.registry; "
            f"print(sorted(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_usage_version_and_bench_help(capsys):
    assert main([]) == 2
    assert "usage: aligngym" in capsys.readouterr().out
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0 and capsys.readouterr().out.startswith("aligngym ")
    with pytest.raises(SystemExit) as stop:
        main(["bench", "--help"])
    out = capsys.readouterr().out
    assert stop.value.code == 0
    for name in ("paper002", "kf-sway", "sghkf-N", "ship-waves-rotary (paper003)"):
        assert name in out
