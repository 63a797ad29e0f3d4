"""How visible surfaces look: flat / Gouraud / normal / depth shading, textures, fog and
blended transparency, run once after visibility for every algorithm."""
