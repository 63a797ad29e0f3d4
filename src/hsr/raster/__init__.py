"""The shared triangle fill (edge functions, top-left rule, depth test, row bands in
parallel) that every raster algorithm paints through."""
