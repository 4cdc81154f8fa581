import numpy as np

from convsss.scene.reference import render_reference


def test_passes_average_and_report(mi, sphere_scene):
    scene = mi.load_dict(sphere_scene(res=16))
    seen = []
    image = render_reference(scene, spp=5, pass_spp=2, seed=1,
                             on_pass=lambda img, done, k, n: seen.append((done, k, n, img.copy())))
    assert [s[:3] for s in seen] == [(2, 0, 3), (4, 1, 3), (5, 2, 3)]
    np.testing.assert_array_equal(image, seen[-1][3])
    assert image.shape == (16, 16, 3) and image.max() > 0
    np.testing.assert_array_equal(image, render_reference(scene, spp=5, pass_spp=2, seed=1))
