"""Lines over or instead of filled triangles: polygon modes, raster hidden lines, exact
vector hidden lines, and SVG output."""
