"""The editor's render thread: the one thread that renders, so that the scene, its kernels and every Dr.Jit call stay
on the thread that loaded them (issue 62: Dr.Jit work launched from the server's request threads crashed the editor).

The server's request threads only queue edits (:meth:`RenderLoop.submit`, which waits for the edit's first pass) and
read what the session published (:meth:`~convsss.editor.EditSession.state`, the image). Between edits the loop
refines the preview, one pass at a time, up to ``max_spp`` samples per pixel; an edit that arrives is taken before the
next pass (a pass in flight ends first: one pass of the preview's ``spp``).

    loop = RenderLoop(session)          # in the thread that made the session
    ... a server thread calls loop.submit({"preset": "ketchup"}) ...
    loop.run()                          # until loop.stop() or Ctrl-C (KeyboardInterrupt, raised here)
"""

import queue
import threading

from ..errors import ConvsssError

#: The samples per pixel a preview refines to while the user is idle (``convsss edit --max-spp``).
MAX_SPP = 256


class _Reply:
    """An edit's answer, handed from the render thread to the request thread that waits for it."""

    def __init__(self):
        self._done, self.error = threading.Event(), None

    def set(self, error=None):
        """The edit is done (published), or failed with ``error``."""
        self.error = error
        self._done.set()

    def wait(self):
        self._done.wait()
        if self.error is not None:
            raise self.error


class RenderLoop:
    """Renders ``session``'s edits and passes on the thread that calls :meth:`run`.

    Parameters
    ----------
    session : EditSession
        Made (and so first rendered) on the thread that will call :meth:`run`.
    max_spp : int
        Passes stop once the image averages this many samples per pixel (0: no passes after an edit's first).
    """

    def __init__(self, session, max_spp=MAX_SPP):
        self.session, self.max_spp = session, int(max_spp)
        self._edits = queue.SimpleQueue()
        self._stopped = False
        self.thread_id = threading.get_ident()  #: the thread that renders (the one that made the loop)

    def submit(self, changes):
        """Queue an edit (keys of :data:`~convsss.editor.session.FIELDS`) and wait until its first pass is published;
        returns the new state. A bad value raises what :meth:`~convsss.editor.EditSession.update` raises (nothing
        changed); a stopped loop, a :class:`ConvsssError`. Call from any thread but the loop's."""
        reply = _Reply()
        if self._stopped:
            raise ConvsssError("the editor is stopping")
        self._edits.put((changes, reply))
        reply.wait()
        return self.state()

    def state(self):
        """The session's published state and the loop's ``max_spp`` (any thread)."""
        return {**self.session.state(), "max_spp": self.max_spp}

    def stop(self):
        """End :meth:`run` after the pass or edit in flight (any thread)."""
        self._stopped = True
        self._edits.put(None)

    def _refining(self):
        return self.session.passes.count * self.session.spp < self.max_spp

    def run(self):
        """Render edits as they come and passes between them, until :meth:`stop`; Ctrl-C raises here. Edits still
        queued when it ends are answered with an error."""
        if threading.get_ident() != self.thread_id:
            raise ConvsssError("the render loop runs on the thread that made it (the one that loaded the scene)")
        try:
            while not self._stopped:
                try:
                    # Waiting in slices: a main thread's Ctrl-C raises between them.
                    item = self._edits.get(block=not self._refining(), timeout=0.25)
                except queue.Empty:
                    if self._refining():
                        self.session.refine()
                    continue
                if item is not None:
                    self._apply(*item)
        finally:
            self._stopped = True
            self._drain()

    def _apply(self, changes, reply):
        try:
            self.session.update(**changes)
            reply.set()
        except (KeyboardInterrupt, SystemExit) as error:
            reply.set(error=ConvsssError("the editor is stopping"))
            raise error
        except BaseException as error:  # the session undid the edit; the request thread reports it
            reply.set(error=error)

    def _drain(self):
        while True:
            try:
                item = self._edits.get_nowait()
            except queue.Empty:
                return
            if item is not None:
                item[1].set(error=ConvsssError("the editor is stopping"))
