"""Instance transforms the core's float32 ray transform cannot invert are conditioned
(cmlt.usd.camera.condition_instance_transform): regular ones pass through unchanged,
a nearly flat one is widened along its thinnest axis only, hopeless ones are refused."""
import numpy as np
import pytest

from cmlt.usd.camera import MIN_AXIS_RATIO, condition_instance_transform


def _m(a, t=(0.0, 0.0, 0.0)):
    m = np.eye(4)
    m[:3, :3] = a
    m[:3, 3] = t
    return m


@pytest.mark.parametrize("a", [np.eye(3), np.diag([1e-4, 1e-4, 1e-4]), np.diag([2.0, 1e-5, 3.0]),
                               np.diag([-1.0, 1.0, 1.0]),
                               [[0.0, -2.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]]])
def test01_regular_transforms_are_unchanged(a):
    m = _m(np.asarray(a, dtype=float), (1.0, -2.0, 3.0))
    out, note = condition_instance_transform(m)
    assert note is None and out is m


def test02_a_flat_transform_is_widened_on_its_thin_axis_only():
    rng = np.random.default_rng(7)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))            # a random rotation (or reflection)
    a = q @ np.diag([-1e-30, 1.5, 5.5])
    m = _m(a, (4.0, 5.0, 6.0))
    out, note = condition_instance_transform(m)
    assert out is not None and "nearly singular" in note
    s_in = np.linalg.svd(a, compute_uv=False)
    s_out = np.linalg.svd(out[:3, :3], compute_uv=False)
    np.testing.assert_allclose(s_out[:2], s_in[:2], rtol=1e-12)  # the wide axes stay
    assert s_out[2] == pytest.approx(5.5 * MIN_AXIS_RATIO, rel=1e-9)
    assert np.sign(np.linalg.det(out[:3, :3])) == np.sign(np.linalg.det(a)) != 0
    np.testing.assert_array_equal(out[:3, 3], m[:3, 3])          # stays where it was
    # the core's float32 inverse is finite and moves points back within float rounding
    inv = np.linalg.inv(out.astype(np.float32))
    assert np.isfinite(inv).all()
    p = np.array([1.0, 2.0, 3.0, 1.0])
    np.testing.assert_allclose((out @ (inv.astype(np.float64) @ p)), p, rtol=1e-3, atol=1e-3)


@pytest.mark.parametrize("m, why", [
    (_m(np.diag([np.nan, 1.0, 1.0])), "not finite"),
    (_m(np.zeros((3, 3))), "point"),
    (_m(np.eye(3) * 1e38), "float32"),
    (_m(np.diag([1e-26, 1e-26, 1e-40])), "smaller"),
])
def test03_hopeless_transforms_are_refused(m, why):
    out, note = condition_instance_transform(m)
    assert out is None and why in note
