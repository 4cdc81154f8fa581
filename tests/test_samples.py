import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.samples import IrradianceSamples, LocalIrradiance, ViewFrame


def test_flux_and_broadcast_irradiance():
    s = IrradianceSamples(np.zeros((2, 3)), [1.0, 2.0], [3.0, 4.0])
    np.testing.assert_array_equal(s.flux, [[3, 3, 3], [8, 8, 8]])
    assert len(s) == 2


@pytest.mark.parametrize("area, irradiance, message", [
    ([1.0, 0.0], [1.0, 1.0], "area"),
    ([1.0, 1.0], [1.0, -1.0], "irradiance"),
    ([1.0], [1.0, 1.0], "2 areas"),
])
def test_bad_samples(area, irradiance, message):
    with pytest.raises(ConvsssError, match=message):
        IrradianceSamples(np.zeros((2, 3)), area, irradiance)


def test_local_irradiance_averages_the_nearest_samples_facing_the_same_way():
    """A thin plate: the top lit (E = 2 at area 1, E = 5 at area 3), the bottom dark, 0.01 mm apart. A point on top
    reads the area-weighted mean of the top's samples only; a point on the bottom reads 0; without normals both
    sides mix."""
    top = np.array([[0.0, 0.0, 0.01], [0.1, 0.0, 0.01]])
    bottom = top - [0.0, 0.0, 0.01]
    samples = IrradianceSamples(np.r_[top, bottom], [1.0, 3.0, 1.0, 1.0], [2.0, 5.0, 0.0, 0.0],
                                np.r_[[[0, 0, 1]] * 2, [[0, 0, -1]] * 2])
    local = LocalIrradiance(samples, neighbours=4)
    points = np.array([[0.05, 0.0, 0.01], [0.05, 0.0, 0.0]])
    e = local(points, np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]))
    np.testing.assert_allclose(e, [[4.25] * 3, [0.0] * 3])
    np.testing.assert_allclose(local(points)[0], [(2 + 15) / 6] * 3)
    lone = local(np.array([[0.05, 0.0, 0.01]]), np.array([[1.0, 0.0, 0.0]]))  # no sample faces +x: the nearest
    assert lone.shape == (1, 3) and local(np.zeros((0, 3))).shape == (0, 3)


def test_look_at_frame_matches_image_axes():
    frame = ViewFrame.look_at([0, 0, 10], [0, 0, 0], up=[0, 1, 0])
    np.testing.assert_allclose(frame.right, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(frame.up, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(frame.to_view([[1, 2, 3]]), [[1, 2, 7]])


def test_frame_from_mitsuba_matrix():
    # Mitsuba's look_at matrix has the columns (left, up, forward, origin).
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = [-1, 0, 0], [0, 1, 0], [0, 0, -1], [0, 0, 10]
    frame = ViewFrame.from_matrix(m)
    np.testing.assert_allclose(frame.right, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(frame.forward, [0, 0, -1])


def test_frame_must_be_orthonormal():
    with pytest.raises(ConvsssError, match="orthonormal"):
        ViewFrame([0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 1])
