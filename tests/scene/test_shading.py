import numpy as np


def test_opaque_shapes_get_mitsubas_direct_light(mi, sphere_scene, object_mask):
    """Off the object, max_depth 2 is direct lighting: the floor matches Mitsuba's `direct` integrator."""
    scene_dict = sphere_scene(floor=True, res=32, spp=16, integrator={"max_depth": 2})
    scene = mi.load_dict(scene_dict)
    ours = np.array(mi.render(scene, seed=1))[..., :3]
    theirs = np.array(mi.render(scene, integrator=mi.load_dict({"type": "direct"}), seed=1))[..., :3]
    floor = ~object_mask(scene) & (theirs.sum(axis=-1) > 0)
    assert floor.sum() > 200
    np.testing.assert_allclose(ours[floor].mean(axis=0), theirs[floor].mean(axis=0), rtol=0.01)


def test_bounces_pick_up_the_objects_glow(mi, sphere_scene, object_mask):
    images = {}
    for depth in (2, 4):
        scene = mi.load_dict(sphere_scene(floor=True, res=32, spp=8, integrator={"max_depth": depth}))
        images[depth] = np.array(mi.render(scene, seed=1))[..., :3]
    floor = ~object_mask(scene)
    assert images[4][floor].sum() > images[2][floor].sum()
