"""The pytest plugin in a fresh test directory (pytester): the ``aligngym_episode``
fixture gives an episode whose truth and sensors agree, ``assert_alignment`` passes
within a bound and fails beyond it with a readable per-episode table, and the
``aligngym_alignment`` fixture checks every start of a multi-start experiment."""
pytest_plugins = ["pytester"]


def test_fixture_and_assertion_in_a_fresh_directory(pytester):
    pytester.makepyfile(test_user=r'''
        import numpy as np
        import pytest
        from aligngym.testing import AlignmentBoundExceeded, assert_alignment

        def test_episode(aligngym_episode):
            ideal = aligngym_episode("static-large-azimuth", seed=1, duration=10.0,
                                     ideal=True)
            assert ideal.dtheta.shape == (ideal.imu_t.size, 3)
            assert ideal.truth.t[-1] == pytest.approx(10.0)
            # a still IMU senses the earth rate: |dtheta| / dt = 15.04 deg/h
            rate = np.linalg.norm(ideal.dtheta.sum(0)) / 10.0
            assert rate == pytest.approx(7.292115e-5, rel=1e-6)

        def test_within_bounds():
            measured = assert_alignment("ekf", "static-large-azimuth", episodes=2,
                                        seed=3, heading_rms_arcmin=600.0,
                                        level_rms_arcmin=2.0, fine_duration=300.0)
            assert measured["diverged"] == 0

        def test_beyond_a_bound():
            with pytest.raises(AlignmentBoundExceeded) as error:
                assert_alignment("ekf", "static-large-azimuth", episodes=2, seed=3,
                                 heading_rms_arcmin=0.01, fine_duration=300.0)
            text = str(error.value)
            assert "heading RMS" in text and "> 0.01'" in text
            assert text.count("\n") == 4          # headline, header, 2 episodes, RMS

        def test_the_fixture_from_every_start(aligngym_alignment):
            measured = aligngym_alignment("kf", "ship-sway-rotary", episodes=2,
                                          start="all", heading_rms_arcmin=20.0,
                                          fine_duration=120.0)
            assert list(measured) == ["mean", "max"]
            with pytest.raises(ValueError, match="valid: mean, max, all"):
                aligngym_alignment("kf", "ship-sway-rotary", start="coarse")
        ''')
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=4)
