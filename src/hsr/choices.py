"""The names enum-like arguments take, as ``Literal`` types, so that an IDE completes them
and a type checker catches a misspelt one. Each equals the tuple the code checks at run
time (``tests/test_package.py`` holds them equal)."""

from __future__ import annotations

from typing import Literal

Algorithm = Literal["zbuffer", "scanline", "raycast", "painter", "newell", "bsp"]
Shading = Literal["auto", "flat", "smooth", "gouraud", "unlit", "normal", "random", "depth"]
Light = Literal["headlight", "studio"]
TextureFilter = Literal["nearest", "bilinear"]
TextureWrap = Literal["repeat", "clamp"]
Transparency = Literal["object", "exact"]
Cull = Literal["none", "back", "front", "front_and_back"]
DepthFuncName = Literal["never", "less", "equal", "lequal", "greater", "notequal", "gequal",
                        "always"]
FrontFaceName = Literal["ccw", "cw"]
PolygonModeName = Literal["fill", "line", "point"]
EdgeKind = Literal["all", "feature"]
UpAxis = Literal["y", "z"]
UpAxisChoice = Literal["auto", "y", "z"]
