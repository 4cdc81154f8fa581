import numpy as np
import pytest

import convsss
from convsss.scene.quick import demo_mesh, quick_scene
from convsss.scene.xmlwriter import object_to_xml, scene_to_xml


def test_written_scene_loads_as_the_dictionary(mi, tmp_path):
    scene_dict = quick_scene(demo_mesh(), convsss.material("marble"), 25.0, 40, 30, floor=True, boundary="null")
    path = tmp_path / "scene.xml"
    path.write_text(scene_to_xml(scene_dict))
    from_xml, from_dict = mi.load_file(str(path)), mi.load_dict(scene_dict)
    for a, b in zip(from_xml.shapes(), from_dict.shapes()):
        np.testing.assert_allclose(list(a.bbox().max), list(b.bbox().max), rtol=1e-5)
    medium = mi.traverse([s for s in from_xml.shapes() if s.interior_medium()][0].interior_medium())
    assert medium["scale"] == pytest.approx(scene_dict["object"]["interior"]["scale"], rel=1e-6)
    assert "VolpathMis" in from_xml.integrator().class_name() or "VolumetricMis" in str(from_xml.integrator())
    assert list(from_xml.sensors()[0].film().size()) == [40, 30]


def test_object_fragment_pastes_into_a_scene(mi, tmp_path):
    obj = convsss.scene.translucent({"type": "sphere", "radius": 3.0}, convsss.material("marble"))
    fragment = object_to_xml("marble", obj)
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">\n{fragment}</scene>\n')
    (shape,) = mi.load_file(str(path)).shapes()
    assert shape.id() == "marble" and shape.interior_medium().class_name() == "HomogeneousMedium"
