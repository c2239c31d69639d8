"""Which MuJoBan object a pixel's colour shows, computed from the task's
public looks (`envs.description.MujobanLooks`), not from one palette.

* `colour_table`: a class per 24-bit colour (box, box on a pad, pad, covered
  pad, red ear, blue ear, none) for given looks;
* `masks`: boolean masks of those classes in a frame, plus the pixels where
  an ear is not looked for (next to a flat object of an ear's hue).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["colour_table", "dilate3", "masks", "FLAT_TOL", "EAR_TOL", "SHADE_SLACK"]


#: Largest difference (0-255, any channel) between a pixel and an untextured
#: surface's computed colour (`MujobanLooks.facing_rgb`) for it to show that
#: surface. Inside an outline rendering is exact (no specular light), so
#: the margin only covers rounding; no wall or floor texture of the environment's
#: styles comes within 13 of the box's colour or 40 of any other.
FLAT_TOL = 4
#: Ears are shaded spheres: a pixel shows an ear when it is the ear's colour
#: times a light between ambient and ambient + diffuse (±``SHADE_SLACK``),
#: within ``EAR_TOL`` (any channel), and shows no flat colour.
EAR_TOL = 10
SHADE_SLACK = 0.01


#: Colour classes of `colour_table`.
_NONE, _BOX, _BOX_ON_PAD, _PAD, _PAD_COVERED, _RED_EAR, _BLUE_EAR = range(7)
_FLATS = ((_BOX, "box"), (_BOX_ON_PAD, "box_on_pad"), (_PAD, "pad"), (_PAD_COVERED, "pad_covered"))


@functools.lru_cache(maxsize=8)
def colour_table(looks) -> tuple[np.ndarray, tuple[int, ...]]:
    """A class per 24-bit colour (uint8 array of 2**24, see `_NONE` ...), for
    `MujobanLooks` ``looks``: an untextured object's colour facing the camera
    within `FLAT_TOL`; an ear's colour times a light between ambient and
    ambient + diffuse (±`SHADE_SLACK`) within `EAR_TOL`, unless it is a
    flat colour. Also returns the flat classes that share an ear's hue (a
    blue box's slanted sides shade like the blue ear)."""
    table = np.zeros(1 << 24, np.uint8)

    def codes(rgb):
        rgb = np.asarray(rgb, np.int64)
        return (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]

    lo = looks.headlight_ambient - SHADE_SLACK
    hi = looks.headlight_ambient + looks.headlight_diffuse + SHADE_SLACK
    span = np.arange(-EAR_TOL, EAR_TOL + 1)
    cube = np.stack(np.meshgrid(span, span, span, indexing="ij"), -1).reshape(-1, 3)
    confusable = set()
    for cls, rgba in ((_RED_EAR, looks.right_ear), (_BLUE_EAR, looks.left_ear)):
        c = np.asarray(rgba[:3], float) * 255.0
        centres = np.rint(np.linspace(lo, hi, 64)[:, None] * c).astype(np.int64)
        cand = np.unique((centres[:, None, :] + cube[None]).reshape(-1, 3), axis=0)
        cand = cand[np.all((cand >= 0) & (cand <= 255), axis=1)]
        scale = cand @ c / (c @ c)
        resid = np.abs(cand - scale[:, None] * c).max(1)
        keep = (resid <= EAR_TOL) & (scale >= lo) & (scale <= hi)
        table[codes(cand[keep])] = cls
        for flat_cls, name in _FLATS:
            rgb = looks.facing_rgb(getattr(looks, name))
            if np.abs(rgb - (rgb @ c) / (c @ c) * c).max() <= EAR_TOL:
                confusable.add(flat_cls)
    fspan = np.arange(-FLAT_TOL, FLAT_TOL + 1)
    fcube = np.stack(np.meshgrid(fspan, fspan, fspan, indexing="ij"), -1).reshape(-1, 3)
    for cls, name in _FLATS:
        cand = np.rint(looks.facing_rgb(getattr(looks, name))).astype(np.int64) + fcube
        cand = cand[np.all((cand >= 0) & (cand <= 255), axis=1)]
        table[codes(cand)] = cls
    return table, tuple(sorted(confusable))


@functools.lru_cache(maxsize=8)
def _confusable_lookup(confusable: tuple[int, ...]) -> np.ndarray:
    """A bool per colour class: True for the classes in ``confusable``."""
    lookup = np.zeros(_BLUE_EAR + 1, bool)
    lookup[list(confusable)] = True
    lookup.flags.writeable = False
    return lookup


def dilate3(mask: np.ndarray) -> np.ndarray:
    """Binary dilation of a 2-D bool ``mask`` by a 3x3 square (outside the
    frame counts as False), computed only over the bounding box of its True
    pixels: equal to ``scipy.ndimage.binary_dilation(mask, np.ones((3, 3)))``."""
    out = np.zeros_like(mask)
    rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
    if not len(rows):
        return out
    r0, r1 = max(rows[0] - 1, 0), min(rows[-1] + 2, mask.shape[0])
    c0, c1 = max(cols[0] - 1, 0), min(cols[-1] + 2, mask.shape[1])
    window = mask[r0:r1, c0:c1]
    grown = window.copy()
    grown[1:] |= window[:-1]
    grown[:-1] |= window[1:]
    wide = grown.copy()
    wide[:, 1:] |= grown[:, :-1]
    wide[:, :-1] |= grown[:, 1:]
    out[r0:r1, c0:c1] = wide
    return out


def masks(frame: np.ndarray, looks) -> dict:
    """Boolean masks of the objects' colours in ``frame`` (see
    `colour_table`): ``box`` (a box's top, yellow or blue on a pad),
    ``pad`` (a pad, red or green when covered), ``box_on_pad`` (a box's top
    showing the pad under it), ``red_ear``, ``blue_ear``,
    and ``unsure``: pixels next to a flat object of an ear's hue, where ears
    are not looked for (treated as hidden). Walls and floors are textured
    and drawn per episode; none of their texels comes near these colours."""
    table, confusable = colour_table(looks)
    code = frame[..., 0].astype(np.int32)  # 24-bit colour, built in place
    code <<= 8
    code |= frame[..., 1]
    code <<= 8
    code |= frame[..., 2]
    cls = table[code]
    unsure = _confusable_lookup(confusable)[cls]
    if unsure.any():
        unsure = dilate3(unsure)
        cls = np.where(unsure & (cls >= _RED_EAR), _NONE, cls)
    box_on_pad = cls == _BOX_ON_PAD
    return dict(
        red_ear=cls == _RED_EAR,
        blue_ear=cls == _BLUE_EAR,
        pad=(cls == _PAD) | (cls == _PAD_COVERED),
        box_on_pad=box_on_pad,
        box=(cls == _BOX) | box_on_pad,
        unsure=unsure,
    )
