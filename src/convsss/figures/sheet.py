"""The display of a figure's panels (its contact sheet is :func:`convsss.sheets.contact_sheet`).

Display: Reinhard et al. 2002's photographic operator (the paper's choice, key 0.18), shared by the panels of one
tone-mapping group: the log-average luminance and the white point come from one anchor image (the figures use the
exact-sum reference of the group's scene), so a panel that is darker than the reference looks darker.
"""

from ..image import Reinhard, srgb_encode

KEY = 0.18


def tonemap_groups(images, groups, anchors=None):
    """sRGB uint8 images, one operator per group anchored on ``anchors[group]`` (default: the group's first image).

    Parameters
    ----------
    images : list of numpy.ndarray, shape (H, W, 3)
        Linear RGB panels (any radiometric unit, one for all).
    groups : list of hashable
        Each image's tone-mapping group.
    anchors : dict, optional
        ``{group: linear RGB image (H, W, 3)}`` that fixes the group's :class:`~convsss.image.Reinhard` operator.

    Returns
    -------
    list of numpy.ndarray, shape (H, W, 3), uint8
        The sRGB-encoded display images, in the order of ``images``.
    """
    anchors = anchors or {}
    operators = {}
    out = []
    for image, group in zip(images, groups):
        if group not in operators:
            operators[group] = Reinhard(anchors.get(group, image), KEY)
        out.append(srgb_encode(operators[group](image)))
    return out
