"""The interactive material editor (``convsss edit``): an :class:`EditSession` keeps a scene prepared and rebuilds
only what an edit changes (:mod:`.session`); :mod:`.server` serves it to a browser on 127.0.0.1 (a JSON API and one
static page, ``static/index.html``)."""

from .session import EditSession

__all__ = ["EditSession"]
