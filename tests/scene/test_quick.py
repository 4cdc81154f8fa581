import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.scene.quick import demo_mesh, quick_scene


def test_bunny_scene_has_the_requested_size(mi):
    scene_dict = quick_scene(demo_mesh(), convsss.material("wholemilk"), 40.0, 64, 48, floor=True)
    scene = mi.load_dict(scene_dict)
    bunny = [s for s in scene.shapes() if s.interior_medium() is not None][0]
    box = bunny.bbox()
    size = np.array(list(box.max)) - np.array(list(box.min))
    assert size.max() == pytest.approx(40.0, rel=1e-4)
    assert box.min[1] == pytest.approx(0.0, abs=1e-3)
    assert len(scene.emitters()) == 2 and len(scene.shapes()) == 2
    assert list(scene.sensors()[0].film().size()) == [64, 48]


@pytest.mark.parametrize("mesh, size, message", [
    ("/nonexistent/mesh.obj", 40.0, "does not exist"),
    (__file__, 40.0, "unknown format"),
    (None, -1.0, "size_mm=-1.0"),
])
def test_bad_input(mesh, size, message):
    with pytest.raises(ConvsssError, match=message):
        quick_scene(mesh or demo_mesh(), convsss.material("wholemilk"), size)
