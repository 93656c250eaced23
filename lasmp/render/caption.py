"""A one-line text caption drawn onto rendered frames (MuJoCo's offscreen renderer has no text).

Drawn with Pillow (a dependency of matplotlib) in matplotlib's bundled DejaVu Sans, white on a
translucent dark band along the top of the frame. Only the band is converted and redrawn, so a
caption costs well under a millisecond per frame.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

BAND_ALPHA = 0.6  # darkening of the band behind the text


@lru_cache(maxsize=8)
def _font(size_px: int):
    import matplotlib
    from PIL import ImageFont

    path = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSansMono-Bold.ttf"
    try:
        return ImageFont.truetype(str(path), size_px)
    except OSError:  # no FreeType in this Pillow build: its bitmap font (fixed size)
        return ImageFont.load_default()


def caption_text(t_s: float, n_waypoints: int | None, v_plf_mps: float | None, collisions: int) -> str:
    """'t 3.42 s   N 7   v_plf 0.83 m/s   collisions 1' (the parts that are known)."""
    parts = [f"t {t_s:5.2f} s"]
    if n_waypoints is not None:
        parts.append(f"N {n_waypoints}")
    if v_plf_mps is not None:
        parts.append(f"v_plf {v_plf_mps:4.2f} m/s")
    parts.append(f"collisions {collisions}")
    return "   ".join(parts)


def draw_caption(frame: np.ndarray, text: str) -> np.ndarray:
    """`frame` (H, W, 3) uint8 with `text` on a dark band along its top; modified in place and returned."""
    from PIL import Image, ImageDraw

    h = frame.shape[0]
    size = max(10, round(h / 28))
    pad = max(2, size // 3)
    band_h = min(size + 2 * pad, h)
    band = frame[:band_h]
    band[:] = (band * (1.0 - BAND_ALPHA)).astype(np.uint8)
    img = Image.fromarray(band)
    ImageDraw.Draw(img).text((pad * 2, pad), text, fill=(255, 255, 255), font=_font(size))
    band[:] = np.asarray(img)
    return frame
