"""``convsss edit``: the interactive material editor, a local web page over an
:class:`~convsss.editor.EditSession` (:mod:`convsss.editor.server`)."""

import dataclasses
import faulthandler
import io
import threading

import click

from ..editor.loop import MAX_SPP
from .main import cli
from .options import integrator_options, scene_source_options


@cli.command()
@scene_source_options(preview=True)
@click.option("--object", "target", help="The translucent object to edit: its shape id, or its index among those the "
                                         "camera sees. [default: the first]")
@click.option("--port", type=click.IntRange(0, 65535), default=0, show_default=True,
              help="Port on 127.0.0.1 (0: a free one); the URL is printed.")
@click.option("--open/--no-open", "open_browser", default=False, show_default=True,
              help="Open the page in the default browser.")
@click.option("--max-spp", type=click.IntRange(0), default=MAX_SPP, show_default=True,
              help="While the page is idle, passes of --spp (each its own seed) refine the preview up to this many "
                   "samples per pixel; the page shows the spp reached and the noise. 0: one pass per edit.")
@integrator_options
def edit(source, spp, sensor, seed, target, port, open_browser, max_spp, **integrator):
    """Edit one translucent object's material in a web page served on 127.0.0.1: the render, a preset picker,
    sliders for colour and mean free path, sigma_s' and sigma_a per channel, eta (dielectric boundaries), the
    multiscale transport's accuracy, the profile model, the profile's plot and per-stage seconds.

    The page renders what `convsss render` renders with the same options (--walk-depth auto by default: random
    walks where diffusion fails on an object, the transport where it holds) and says which. Where it walks, a new
    material prepares the scene again. With the transport (--walk-depth 0, or where diffusion holds) the scene, the
    surface samples and their irradiance are kept between edits: a new material of the same eta, a new model or
    accuracy rebuilds the transports and shades again; a new eta prepares the samples again. The preview is
    --width/--height (default 256x256) at --spp (default 1), refined by more passes while the page is idle
    (--max-spp). One thread renders (this command's), the page's requests queue edits to it; an edit waits at most
    for the pass in flight. Ctrl-C stops the server.

    \b
    Examples:
      convsss edit scene.xml --object bunny --port 8123
      convsss edit --mesh bunny --material wholemilk --size-mm 40 --floor --width 512 --height 512
    """
    from ..pipeline.params import render_params

    quick = source.quick
    defaults = {"specular": "phong"} if quick else {}
    render_params(integrator, defaults)  # bad values fail before anything is loaded
    from ..backend import load_mitsuba
    from ..editor import EditSession
    from ..editor.loop import RenderLoop
    from ..editor.server import EditorServer
    from ..outputs import pick_sensor
    from ..pipeline.integrator import scene_parameters

    load_mitsuba()
    try:
        faulthandler.enable()  # a crash in compiled code names where it happened
    except (AttributeError, ValueError, io.UnsupportedOperation):  # a stderr without a file (a test's runner)
        pass
    # The quick scene's preview in a box filter: uncorrelated pixel noise, which the denoised preview removes.
    scene = dataclasses.replace(source, width=source.width or 256, height=source.height or 256, rfilter="box").load()
    base = scene_parameters(scene) or defaults
    camera = pick_sensor(scene, sensor)
    server = EditorServer(None, "127.0.0.1", port)  # the port is taken (or refused) before the first render
    try:
        click.echo("rendering the first preview...", err=True)
        session = EditSession(scene, render_params(integrator, base), target=target, spp=spp or 1, seed=seed,
                              sensor=camera)
    except BaseException:
        server.server_close()
        raise
    server.loop = loop = RenderLoop(session, max_spp)
    if len(session.objects) > 1:
        click.echo(f"editing {session.target.name!r}, one of {len(session.objects)} translucent objects "
                   "(--object picks another)", err=True)
    click.echo(f"convsss edit: {server.url}  (first render {session.last['seconds']['total']:.1f} s; Ctrl-C stops)")
    # The server answers from its own threads; this thread, which loaded the scene, renders every edit and pass.
    serving = threading.Thread(target=server.serve_forever, name="editor-server", daemon=True)
    serving.start()
    if open_browser:
        import webbrowser

        webbrowser.open(server.url)
    try:
        loop.run()
    finally:
        server.shutdown()
        server.server_close()
