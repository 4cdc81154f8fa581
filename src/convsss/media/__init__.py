"""A material as Mitsuba holds it, below both the scene's authoring (:mod:`convsss.scene`) and the render
(:mod:`convsss.pipeline`), which both read it and neither of which it imports:

- :mod:`.dicts`: a :class:`~convsss.materials.Material` written as a Mitsuba medium (``sigma_t / scale / albedo``),
  its boundary and a translucent shape;
- :mod:`.named`: the ``convsss_medium`` plugin, a medium named in a scene file by a preset or by a colour and a mean
  free path, and the registry of which medium came from which name.
"""
