"""Colours of esp_gym's pictures: the rgb_array renderer (render.py) and the Rerun recordings
(recorder.py) draw the string, body, pivot, targets and forces alike. RGB, uint8 components.
"""
import numpy as np

#: Anchors of the strain colour ramp, low to high: purple, blue, teal, green, yellow (a
#: perceptually ordered, viridis-like ramp, defined here and interpolated to :data:`STRAIN_LUT`).
STRAIN_RAMP = np.array([(68, 1, 84), (65, 68, 135), (42, 120, 142), (34, 168, 132),
                        (122, 209, 81), (253, 231, 37)], dtype=float)
#: 256-entry lookup table of the strain ramp, (256, 3) uint8.
STRAIN_LUT = np.stack([np.interp(np.linspace(0, 1, 256), np.linspace(0, 1, len(STRAIN_RAMP)),
                                 STRAIN_RAMP[:, c]) for c in range(3)], axis=1).round().astype(np.uint8)

# -- the renderer's frame -------------------------------------------------------------------------
BACKGROUND = (250, 250, 247)
GRID_MINOR = (232, 232, 228)
GRID_MAJOR = (212, 212, 208)
GRID_AXIS = (182, 182, 190)
INK = (70, 70, 78)          #: labels, axes icon, panel divider

# -- the scene ------------------------------------------------------------------------------------
BODY = (226, 150, 84)       #: body base colour (the renderer shades it)
PIVOT = (38, 38, 46)
TARGET = (214, 30, 50)
FORCE = (190, 40, 170)      #: the pivot-force arrow
TORQUE = (40, 150, 190)     #: the body-torque arrow (recordings)
TRAIL = (90, 120, 200)      #: the load's trail (recordings)
WIND = (110, 170, 210)      #: the wind arrow (env recordings)
PUSH = (230, 120, 20)       #: the push arrow (env recordings)
HOOK_TENSION = (60, 140, 60)  #: the hook-tension arrow (env recordings)

# -- time series (recordings) ---------------------------------------------------------------------
#: The first eight colours of matplotlib's tab10 cycle.
TAB10 = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
         (227, 119, 194), (127, 127, 127)]
BLACK = (20, 20, 20)


def pack_rgba(rgb: np.ndarray) -> np.ndarray:
    """(n, 3) uint8 colours -> (n,) uint32 0xRRGGBBAA (Rerun's packed colour, opaque)."""
    c = rgb.astype(np.uint32)
    return (c[:, 0] << 24) | (c[:, 1] << 16) | (c[:, 2] << 8) | np.uint32(255)


#: :data:`STRAIN_LUT` packed for Rerun, (256,) uint32.
STRAIN_RGBA = pack_rgba(STRAIN_LUT)
