"""Scene dictionaries (Mitsuba's ``load_dict`` form) written as Mitsuba 3 XML scene files.

Covers what the scenes of this package use: nested plugins (shape, bsdf, medium, phase, emitter, sensor, film,
sampler, rfilter, integrator, texture, volume), ``rgb`` values, numbers, booleans, strings, 3-vectors and transforms.
"""

from xml.sax.saxutils import quoteattr

import numpy as np

from ..errors import ConvsssError

#: Plugin category of a nested dictionary, by the key it sits under.
NESTED = {"integrator": "integrator", "sensor": "sensor", "film": "film", "sampler": "sampler",
          "rfilter": "rfilter", "bsdf": "bsdf", "interior": "medium", "exterior": "medium", "phase": "phase",
          "emitter": "emitter", "medium": "medium"}
#: Plugin category of a top-level object, by its type.
SHAPES = {"obj", "ply", "serialized", "sphere", "cube", "rectangle", "disk", "cylinder", "shapegroup", "instance"}
EMITTERS = {"point", "spot", "directional", "constant", "envmap", "area", "projector", "directionalarea"}
VOLUMES = {"gridvolume", "constvolume"}
POINT_KEYS = {"position", "origin", "target", "center"}


def _numbers(values):
    return ", ".join(repr(float(v)) for v in values)


def _transform_matrix(value):
    matrix = getattr(value, "matrix", value)
    return np.array(matrix, dtype=np.float64).reshape(4, 4)


def _category(key, value, top_level):
    if not top_level and key in NESTED:
        return NESTED[key]
    if top_level and key in ("integrator", "sensor"):
        return key
    kind = value["type"]
    if kind in SHAPES:
        return "shape"
    if kind in EMITTERS:
        return "emitter"
    if kind == "rgb" or kind == "spectrum":
        return None
    if kind in VOLUMES:
        return "volume"
    if not top_level:
        return "texture"
    raise ConvsssError(f"cannot write scene object {key!r} of type {kind!r} as XML")


def _element(key, value, indent, top_level=False):
    pad = "    " * indent
    if isinstance(value, dict):
        if value.get("type") == "rgb":
            return [f'{pad}<rgb name={quoteattr(key)} value="{_numbers(np.ravel(value["value"]))}"/>']
        tag = _category(key, value, top_level)
        attrs = f'type={quoteattr(value["type"])}'
        if tag in ("medium", "volume", "texture"):
            attrs += f" name={quoteattr(key)}"
        elif top_level and tag in ("shape", "emitter"):
            attrs += f" id={quoteattr(key)}"
        lines = [f"{pad}<{tag} {attrs}>"]
        for k, v in value.items():
            if k != "type":
                lines += _element(k, v, indent + 1)
        return lines + [f"{pad}</{tag}>"]
    if isinstance(value, bool):
        return [f'{pad}<boolean name={quoteattr(key)} value="{str(value).lower()}"/>']
    if isinstance(value, (int, np.integer)):
        return [f'{pad}<integer name={quoteattr(key)} value="{int(value)}"/>']
    if isinstance(value, (float, np.floating)):
        return [f'{pad}<float name={quoteattr(key)} value="{float(value)!r}"/>']
    if isinstance(value, str):
        return [f"{pad}<string name={quoteattr(key)} value={quoteattr(value)}/>"]
    if hasattr(value, "matrix") or key == "to_world":
        m = _transform_matrix(value)
        return [f"{pad}<transform name={quoteattr(key)}>", f'{pad}    <matrix value="{_numbers(m.ravel())}"/>',
                f"{pad}</transform>"]
    array = np.ravel(np.asarray(value, dtype=np.float64))
    if array.size == 3:
        tag = "point" if key in POINT_KEYS else "vector"
        return [f'{pad}<{tag} name={quoteattr(key)} value="{_numbers(array)}"/>']
    raise ConvsssError(f"cannot write the value of {key!r} ({type(value).__name__}) as XML")


def scene_to_xml(scene):
    """The XML text of a scene dictionary (``{"type": "scene", ...}``)."""
    if scene.get("type") != "scene":
        raise ConvsssError("only a dictionary with type 'scene' can be written as a scene file")
    lines = ['<scene version="3.0.0">']
    for key, value in scene.items():
        if key != "type":
            lines += _element(key, value, 1, top_level=True)
    return "\n".join(lines + ["</scene>", ""])


def object_to_xml(key, shape):
    """The XML element of one shape dictionary (e.g. a translucent object to paste into an existing scene)."""
    return "\n".join(_element(key, shape, 0, top_level=True)) + "\n"
