"""From world to window: render state, conventions, transform, clipping, face culling and
the window-space triangle set-up every fill shares."""
