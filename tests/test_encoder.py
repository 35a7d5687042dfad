"""The gimbal angle encoders (sensors/encoder.py) against hand values: a 20-bit count by
default, offsets drawn once per episode from the episode's stream, readings rounded to
the nearest count after the offset is added, bad settings refused in one line."""
import math

import numpy as np
import pytest

from aligngym.sensors.encoder import GimbalEncoderSpec


def test_the_default_is_a_20_bit_encoder_without_offset():
    spec = GimbalEncoderSpec()
    assert spec.resolution == pytest.approx(2 * math.pi / 1048576, rel=1e-15)
    assert spec.offset_sigma == 0.0
    np.testing.assert_array_equal(spec.draw_offsets(np.random.default_rng(1)), [0.0, 0.0])


@pytest.mark.parametrize("field", ["resolution", "offset_sigma"])
@pytest.mark.parametrize("value", [-1e-9, -1.0, math.nan, math.inf, -math.inf])
def test_bad_settings_are_refused_in_one_line(field, value):
    with pytest.raises(ValueError, match=f"^{field} must be finite and >= 0 rad, got "):
        GimbalEncoderSpec(**{field: value})


def test_zero_is_allowed_for_both():
    spec = GimbalEncoderSpec(resolution=0.0, offset_sigma=0.0)
    angles = np.array([[0.123456789, -2.5]])
    np.testing.assert_array_equal(spec.measure(angles, np.zeros(2)), angles)


@pytest.mark.parametrize("axes", [1, 2, 3])
def test_offsets_are_sigma_times_the_streams_next_normals(axes):
    """sigma x the next `axes` standard normals of the episode's generator (the same
    stream as a copy of it gives)."""
    spec = GimbalEncoderSpec(offset_sigma=1e-3)
    rng, twin = np.random.default_rng(7), np.random.default_rng(7)
    offsets = spec.draw_offsets(rng, axes)
    assert offsets.shape == (axes,)
    np.testing.assert_array_equal(offsets, 1e-3 * twin.standard_normal(axes))


def test_readings_round_to_the_nearest_count_after_the_offset():
    """Resolution 0.1 rad, offsets (+0.03, -0.02): 0.14 + 0.03 = 0.17 -> 0.2; 0.14 - 0.02 =
    0.12 -> 0.1; -0.14 + 0.03 = -0.11 -> -0.1; -0.16 - 0.02 = -0.18 -> -0.2."""
    spec = GimbalEncoderSpec(resolution=0.1)
    angles = np.array([[0.14, 0.14], [-0.14, -0.16]])
    reading = spec.measure(angles, np.array([0.03, -0.02]))
    assert reading.shape == (2, 2) and reading.dtype == float
    np.testing.assert_allclose(reading, [[0.2, 0.1], [-0.1, -0.2]], atol=1e-15)


def test_a_reading_is_within_half_a_count_of_angle_plus_offset():
    """The quantisation error of many readings: within +-resolution / 2, spread over the
    whole count (not a floor or a ceiling)."""
    spec = GimbalEncoderSpec()
    angles = np.random.default_rng(3).uniform(-math.pi, math.pi, (2000, 2))
    offsets = np.array([1e-4, -2e-4])
    error = spec.measure(angles, offsets) - (angles + offsets)
    half = spec.resolution / 2
    assert np.all(np.abs(error) <= half * (1 + 1e-9))
    assert error.min() < -0.9 * half and error.max() > 0.9 * half
    counts = spec.measure(angles, offsets) / spec.resolution
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)


def test_a_spec_is_immutable_and_hashable():
    """Specs key the caches of the runs that use them: no field can change after it."""
    import dataclasses
    spec = GimbalEncoderSpec(offset_sigma=1e-4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.resolution = 0.0
    assert hash(spec) == hash(GimbalEncoderSpec(offset_sigma=1e-4))
