"""Paper for a plotter: page sizes (``A4``, ``A3``, ``letter``, ``210x297mm``) and the
fit of an image onto a page inside its margin (uniform scale, centred)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from ..errors import OutputError

__all__ = ["PAPER_MM", "Page", "parse_page"]

# ISO 216 and US sizes, portrait (width, height) in millimetres.
PAPER_MM = {"a6": (105.0, 148.0), "a5": (148.0, 210.0), "a4": (210.0, 297.0),
            "a3": (297.0, 420.0), "a2": (420.0, 594.0), "a1": (594.0, 841.0),
            "a0": (841.0, 1189.0), "letter": (215.9, 279.4), "legal": (215.9, 355.6),
            "tabloid": (279.4, 431.8)}
_UNIT_MM = {"mm": 1.0, "cm": 10.0, "in": 25.4}
_LARGEST_MM = 100_000.0  # 100 m: a bigger page is a typo


@dataclass(frozen=True)
class Page:
    """A page ``width_mm`` x ``height_mm`` with ``margin_mm`` on every side. ``orientation``
    (``auto``, ``portrait``, ``landscape``): ``auto`` turns a named paper to match the
    drawing (landscape for a wide image)."""

    width_mm: float
    height_mm: float
    margin_mm: float = 10.0
    orientation: str = "auto"

    def size_for(self, width_px: int, height_px: int) -> tuple:
        """(width, height) in mm of the page a ``width_px`` x ``height_px`` image goes on."""
        w, h = self.width_mm, self.height_mm
        if self.orientation == "auto":
            wide = width_px > height_px
            return (max(w, h), min(w, h)) if wide else (min(w, h), max(w, h))
        return (max(w, h), min(w, h)) if self.orientation == "landscape" else (w, h)

    def fit(self, width_px: int, height_px: int) -> tuple:
        """``(page_w, page_h, scale, dx, dy)``: the page size in mm, and the map from image
        pixels to page millimetres (x_mm = scale * x + dx), the image as large as the margin
        allows and centred. Raises :class:`~hsr.errors.OutputError` when the margins leave
        no room."""
        page_w, page_h = self.size_for(width_px, height_px)
        room_w, room_h = page_w - 2 * self.margin_mm, page_h - 2 * self.margin_mm
        if room_w <= 0 or room_h <= 0:
            raise OutputError(f"a {page_w:g} x {page_h:g} mm page with {self.margin_mm:g} mm "
                              "margins has no room for the drawing")
        scale = min(room_w / width_px, room_h / height_px)
        dx = (page_w - scale * width_px) / 2
        dy = (page_h - scale * height_px) / 2
        return page_w, page_h, scale, dx, dy


def parse_page(text: str, margin_mm: float = 10.0) -> Page:
    """A :class:`Page` from ``A4``, ``a3-landscape``, ``letter-portrait``, ``300x200mm``,
    ``11x17in`` or ``40x30cm``. Raises :class:`~hsr.errors.OutputError` for anything
    else, or a margin that is negative or not a number."""
    if isinstance(margin_mm, bool) or not isinstance(margin_mm, (int, float)) \
            or not math.isfinite(margin_mm) or margin_mm < 0:
        raise OutputError(f"the page margin must be a number of mm >= 0, got {margin_mm!r}")
    if not isinstance(text, str):
        raise OutputError(f"page must be a name like A4 or a size like 210x297mm, got "
                          f"{text!r}")
    name = text.strip().lower()
    orientation = "auto"
    for suffix in ("landscape", "portrait"):
        if name.endswith("-" + suffix):
            name, orientation = name[:-len(suffix) - 1], suffix
    if name in PAPER_MM:
        w, h = PAPER_MM[name]
        return Page(w, h, float(margin_mm), orientation)
    match = re.fullmatch(r"(\d+(?:\.\d*)?)x(\d+(?:\.\d*)?)(mm|cm|in)", name)
    if match is None:
        raise OutputError(f"unknown page {text!r}: give one of "
                          f"{', '.join(k.upper() if k[0] == 'a' else k for k in PAPER_MM)} "
                          "or a size like 210x297mm")
    unit = _UNIT_MM[match.group(3)]
    w, h = float(match.group(1)) * unit, float(match.group(2)) * unit
    if not (0 < w <= _LARGEST_MM and 0 < h <= _LARGEST_MM):
        raise OutputError(f"page {text!r}: each side must be in 0..{_LARGEST_MM:g} mm")
    return Page(w, h, float(margin_mm), "portrait" if orientation == "auto" else orientation)
