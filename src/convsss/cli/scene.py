"""``convsss scene``: write a translucent object, from a preset and a size, as a Mitsuba 3 scene file."""

from pathlib import Path

import click

from ..files import check_outputs, write_text
from .main import cli


@cli.command()
@click.option("--mesh", default="bunny", show_default=True, type=click.Path(dir_okay=False),
              help="Mesh file (.obj, .ply, .serialized, y up); 'bunny' is the bundled Stanford bunny.")
@click.option("--material", required=True, help="Preset name (see `convsss materials`), e.g. wholemilk.")
@click.option("--size-mm", required=True, type=float, help="The object's largest side in mm.")
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Scene file to write (default: print to stdout).")
@click.option("--boundary", type=click.Choice(["dielectric", "roughdielectric", "null"]), default="dielectric",
              show_default=True, help="The object's surface BSDF (null: index-matched, eta = 1).")
@click.option("--unit-mm", type=float, default=1.0, show_default=True,
              help="mm per scene unit: the medium's sigma_t is written per scene unit.")
@click.option("--floor", is_flag=True, help="Add a grey floor under the object.")
@click.option("--width", type=int, default=800, show_default=True, help="Film width in pixels.")
@click.option("--height", type=int, default=800, show_default=True, help="Film height in pixels.")
@click.option("--spp", type=int, default=16, show_default=True, help="Samples per pixel of the scene's sampler.")
@click.option("--object-only", is_flag=True,
              help="Write only the object's <shape> element (medium and BSDF inside), to paste into your own scene.")
def scene(mesh, material, size_mm, output, boundary, unit_mm, floor, width, height, spp, object_only):
    """Write a scene with a translucent object made of a preset material, scaled to --size-mm.

    The medium is written in the sigma_t/scale/albedo form that Mitsuba's RGB mode needs (sigma_t <= 1 and the
    largest value in scale, per scene unit); the scene has a camera, a key light, a back light and Mitsuba's
    volpathmis without Russian roulette as integrator, so it renders as it is with plain Mitsuba (ground truth),
    with `convsss render SCENE` and with `convsss reference SCENE`.

    \b
    Examples:
      convsss scene --material wholemilk --size-mm 40 --boundary null -o milk.xml
      convsss scene --mesh dragon.ply --material marble --size-mm 100 --object-only
    """
    from ..materials import material as lookup_material
    from ..scene.quick import demo_mesh, quick_scene
    from ..scene.xmlwriter import object_to_xml, scene_to_xml

    mesh_path = demo_mesh() if mesh == "bunny" else Path(mesh)
    if output:
        check_outputs([output], [mesh_path])
    scene_dict = quick_scene(mesh_path, lookup_material(material), size_mm, width, height, spp, floor, boundary,
                             unit_mm)
    text = object_to_xml("object", scene_dict["object"]) if object_only else scene_to_xml(scene_dict)
    if output:
        write_text(output, text)
        click.echo(f"wrote {output}")
    else:
        click.echo(text, nl=False)
