"""``convsss scene``: write a translucent object, from a preset and a size, as a Mitsuba 3 scene file."""

import os
import re
from pathlib import Path

import click

from ..errors import ConvsssError
from ..files import check_outputs, write_text
from ..media.dicts import BOUNDARIES
from ..scene.quick import HEIGHT, SPP, WIDTH
from ..scene.source import source_material
from .main import cli
from .options import color_options

#: What an object's id may be: a name Mitsuba, XML and ``--profile NAME=...`` all take (no dots, no spaces).
ID_PATTERN = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")


def object_id(mesh_path, given=None):
    """The object's id: ``given``, or the mesh file's name without its extension, made a valid id."""
    if given is not None:
        if not ID_PATTERN.fullmatch(given):
            raise ConvsssError(f"--id {given!r} is not allowed: an id is a letter or _ followed by letters, digits, "
                               "_ or -")
        return given
    name = re.sub(r"[^A-Za-z0-9_-]", "_", Path(mesh_path).stem)
    return name if ID_PATTERN.fullmatch(name) else f"mesh_{name}"


def mesh_filename(mesh_path, output):
    """The mesh's path as the scene file names it: relative to the output file's folder (Mitsuba resolves a scene's
    relative file names there), absolute when printed or on another drive."""
    mesh_path = Path(mesh_path).resolve()
    if output is None:
        return str(mesh_path)
    try:
        return Path(os.path.relpath(mesh_path, Path(output).resolve().parent)).as_posix()
    except ValueError:  # another drive (Windows)
        return str(mesh_path)


@cli.command()
@click.option("--mesh", default="bunny", show_default=True, type=click.Path(dir_okay=False),
              help="Mesh file (.obj, .ply, .serialized, y up); 'bunny' is the bundled Stanford bunny.")
@click.option("--material", help="Preset name (see `convsss materials`), e.g. wholemilk; or --color and --mfp-mm.")
@color_options
@click.option("--size-mm", required=True, type=float, help="The object's largest side in mm.")
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Scene file to write (default: print to stdout).")
@click.option("--boundary", type=click.Choice(BOUNDARIES), default="dielectric",
              show_default=True, help="The object's surface BSDF (null: index-matched, eta = 1).")
@click.option("--unit-mm", type=float, default=1.0, show_default=True,
              help="mm per scene unit: the medium's sigma_t is written per scene unit.")
@click.option("--floor", is_flag=True, help="Add a grey floor under the object.")
@click.option("--width", type=int, default=WIDTH, show_default=True, help="Film width in pixels.")
@click.option("--height", type=int, default=HEIGHT, show_default=True, help="Film height in pixels.")
@click.option("--spp", type=int, default=SPP, show_default=True, help="Samples per pixel of the scene's sampler.")
@click.option("--object-only", is_flag=True,
              help="Write only the object's <shape> element (medium and BSDF inside), to paste into your own scene.")
@click.option("--volume", type=click.Path(dir_okay=False),
              help="A Mitsuba grid volume file (.vol, e.g. written by mitsuba.VolumeGrid(array).write) of the albedo, "
                   "1 or 3 channels in [0, 1]: the interior is then a heterogeneous medium of the material's "
                   "extinction and this albedo, the grid stretched over the object's bounding box (z, y, x cells "
                   "along the scene's axes, y up); the material's own albedo is not used.")
@click.option("--color-texture", type=click.Path(dir_okay=False),
              help="A bitmap (PNG, EXR, JPEG) of the surface colour, the total diffuse reflectance per texel in (0, 1) "
                   "(PNG and JPEG read as sRGB), on the mesh's texture coordinates (it needs them); with --mfp-mm "
                   "(and --eta, --color-model), instead of --color. The interior is then a convsss_medium of this "
                   "colour map: coefficients varying along the surface, constant with depth "
                   "(docs/guide/scene-files.md). It renders with `convsss render` and `convsss reference` (its "
                   "heterogeneous equivalent), not with plain Mitsuba.")
@click.option("--id", "shape_id",
              help="The object's id (its name in `convsss render --profile ID=...` and the stats). Default: the mesh "
                   "file's name without extension.")
def scene(mesh, material, color, mfp_mm, eta, color_model, size_mm, output, boundary, unit_mm, floor, width, height,
          spp, object_only, volume, color_texture, shape_id):
    """Write a scene with a translucent object made of a preset material (or of --color and --mfp-mm, inverted to
    coefficients under --color-model), scaled to --size-mm.

    The medium is written in the sigma_t/scale/albedo form that Mitsuba's RGB mode needs (sigma_t <= 1 and the
    largest value in scale, per scene unit); the scene has a camera, a key light, a back light and Mitsuba's
    volpathmis without Russian roulette as integrator, so it renders as it is with plain Mitsuba (ground truth),
    with `convsss render SCENE` and with `convsss reference SCENE`. A colour is written as the coefficients it
    inverts to; to name a preset or a colour in a file you write, use <medium type="convsss_medium">
    (docs/guide/scene-files.md).
    With -o the mesh's path is written relative to the output's folder (keep them together when moving them);
    printed, it is absolute.

    \b
    Examples:
      convsss scene --material wholemilk --size-mm 40 --boundary null -o milk.xml
      convsss scene --mesh dragon.ply --material marble --size-mm 100 --object-only
      convsss scene --color 0.8,0.5,0.4 --mfp-mm 2 --size-mm 40 -o colour.xml
      convsss scene --mesh cube.obj --material marble --size-mm 30 --volume veins.vol -o veined.xml
      convsss scene --mesh head.obj --color-texture skin.png --mfp-mm 1.5 --size-mm 200 -o painted.xml
    """
    from ..scene.quick import demo_mesh, quick_scene
    from ..scene.xmlwriter import object_to_xml, scene_to_xml

    mesh_path = demo_mesh() if mesh == "bunny" else Path(mesh)
    name = object_id(mesh_path, shape_id)
    if output:
        check_outputs([output], [mesh_path] + [f for f in (volume, color_texture) if f])
    if color_texture is not None:
        given = "--material" if material else "--color" if color else "--volume" if volume else None
        if given:
            raise ConvsssError(f"--color-texture and {given} given: the texture is the colour; give it with --mfp-mm")
        if mfp_mm is None:
            raise ConvsssError("--color-texture needs --mfp-mm: the reduced mean free path under the colour map")
        if not Path(color_texture).is_file():
            raise ConvsssError(f"colour texture {color_texture!r} does not exist")
        color = "0.5"  # a stand-in for the boundary and the scene's layout: the texture gives the colour
    made = source_material(material, color, mfp_mm, eta, color_model, boundary)
    if made is None:
        raise ConvsssError("no material: give --material NAME, or --color and --mfp-mm")
    if volume is not None:
        from ..backend import load_mitsuba
        from ..pipeline.media import check_albedo_grid

        load_mitsuba()
        check_albedo_grid(volume)
    scene_dict = quick_scene(mesh_path, made, size_mm, width, height, spp, floor, boundary, unit_mm,
                             albedo_volume=None if volume is None else mesh_filename(volume, output),
                             color_texture=None if color_texture is None else mesh_filename(color_texture, output),
                             color_model=color_model or "exact")
    shape = {**scene_dict["object"], "filename": mesh_filename(mesh_path, output)}
    if object_only:
        text = object_to_xml(name, shape)
    else:
        if name != "object" and name in scene_dict:
            raise ConvsssError(f"--id {name!r} is taken by the scene's {name.replace('_', ' ')}: choose another id")
        text = scene_to_xml({(name if key == "object" else key): (shape if key == "object" else value)
                             for key, value in scene_dict.items()})
    if output:
        write_text(output, text)
        click.echo(f"wrote {output}")
    else:
        click.echo(text, nl=False)
