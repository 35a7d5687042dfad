"""The generic Gaussian filter: an analytic linear case, batch independence, guards, and
the registry."""
import subprocess
import sys

import numpy as np
import pytest

from estimators.filters import FILTERS, make_filter


def scalar_problem(batch=3):
    Phi = np.ones((batch, 1, 1))
    Q = np.zeros((batch, 1, 1))
    H = np.ones((batch, 1, 1))
    R = np.full((batch, 1, 1), 0.25)
    return Phi, Q, H, R


def test_kf_estimates_a_constant_like_the_weighted_mean():
    rng = np.random.default_rng(3)
    Phi, Q, H, R = scalar_problem()
    z = 2.0 + 0.5 * rng.standard_normal((40, 3))
    f = make_filter("kf")
    f.reset(np.zeros((3, 1)), np.full((3, 1, 1), 4.0), m=1)
    for k in range(40):
        f.predict(Phi, Q)
        f.update(z[k][:, None], H, R, t=float(k))
    info = 1 / 4.0 + 40 / 0.25
    np.testing.assert_allclose(f.P[:, 0, 0], 1 / info, rtol=1e-12)
    np.testing.assert_allclose(f.x[:, 0], z.sum(0) / 0.25 / info, rtol=1e-12)


def test_nan_measurement_flags_only_its_episode():
    Phi, Q, H, R = scalar_problem()
    f, g = make_filter("kf"), make_filter("kf")
    for filt in (f, g):
        filt.reset(np.zeros((3, 1)), np.full((3, 1, 1), 4.0), m=1)
    for k in range(5):
        z = np.full((3, 1), 1.0 + k)
        bad = z.copy()
        if k == 2:
            bad[1, 0] = np.nan
        f.predict(Phi, Q); f.update(bad, H, R, t=10.0 + k)
        g.predict(Phi, Q); g.update(z, H, R, t=10.0 + k)
    assert list(f.health.diverged) == [False, True, False]
    assert f.health.time[1] == 12.0 and "NaN" in f.health.reason[1]
    assert np.all(np.isfinite(f.x)) and np.all(np.isfinite(f.P))
    np.testing.assert_array_equal(f.x[[0, 2]], g.x[[0, 2]])


def test_non_positive_definite_covariance_is_flagged_not_propagated():
    Phi, Q, H, R = scalar_problem()
    R = R.copy()
    R[0] = -10.0  # S = P + R < 0 for episode 0
    f = make_filter("imakf")
    f.reset(np.zeros((3, 1)), np.full((3, 1, 1), 4.0), m=1)
    f.predict(Phi, Q)
    f.update(np.ones((3, 1)), H, R, t=1.0)
    assert list(f.health.diverged) == [True, False, False]
    assert "not positive definite" in f.health.reason[0]
    assert np.all(np.isfinite(f.P))


def test_registry_and_unknown_name():
    assert {"kf", "sakf", "makf", "imakf"} <= set(FILTERS)
    with pytest.raises(KeyError, match="known filters: ckf, imakf, imakf-n, kf, makf"):
        make_filter("ukf-typo")


def test_cli_unknown_filter_lists_known_names(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "scenarios.cli", "bench", "paper003",
                           "--filters", "kf,nope", "--episodes", "1", "--out", str(tmp_path)],
                          capture_output=True, text=True)
    assert proc.returncode != 0
    assert "unknown filter 'nope'; known filters: ckf, imakf" in proc.stderr
    assert "Traceback" not in proc.stderr
