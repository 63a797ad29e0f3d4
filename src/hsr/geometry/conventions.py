"""The conventions hsr follows, in prose. They are OpenGL's, stated once.

Axes and camera
---------------
World space is right-handed. The camera looks down its own -Z axis with +Y up (eye
space), exactly as ``gluLookAt`` builds it. The perspective projection is
``gluPerspective``'s matrix, the orthographic one is ``glOrtho``'s; both map eye space to
homogeneous *clip space* ``(x, y, z, w)``. For perspective ``w = -z_eye``.

Clip space and NDC
------------------
A point is inside the view volume when ``-w <= x, y, z <= w``. Triangles are clipped in
homogeneous clip space, before the divide, against the near and far planes
(``z >= -w`` and ``z <= w``) and against a guard band in x and y (Sutherland-Hodgman,
:mod:`hsr.geometry.clip`). Clipping before the divide is what keeps a triangle that crosses the eye
plane (``w`` changes sign) from wrapping around through infinity. After the divide,
``x_ndc = x / w`` etc. lie in [-1, 1].

Window space
------------
``x_window = (x_ndc + 1) * width / 2`` and ``y_window = (y_ndc + 1) * height / 2``, with
``y_window`` pointing *up* as in OpenGL; ``depth_window = (f - n) / 2 * z_ndc + (f + n) / 2``
where ``(n, f)`` is ``glDepthRange`` (default ``(0, 1)``). Image row 0 of every hsr buffer
is the *top* of the picture (row ``r`` holds window rows centred at
``y_window = height - r - 0.5``). Pixel ``(x, y)`` of an image is sampled at its centre,
``(x + 0.5, y + 0.5)`` in image coordinates.

Coverage and the fill rule
--------------------------
Window x, y are snapped to 1/256 pixel (8 sub-pixel bits, as Mesa's llvmpipe does) and the
three edge functions are evaluated in exact 64-bit integer arithmetic, so the decision
"is this pixel centre inside" is exact and the same for both triangles that share an
edge. A centre lying exactly on an edge belongs to the triangle for which that edge is a
*left* edge or a *top* edge in image orientation (the D3D / llvmpipe "top-left" rule; in
OpenGL's y-up window space it reads "left or bottom"). Consequently an edge shared by two
triangles is covered exactly once: no cracks, no double hits. We measured this rule on
Mesa llvmpipe with pixel centres placed exactly on edges; ``tests/test_opengl.py`` keeps
checking it.

Depth: why window depth is linear in screen space (1/z)
-------------------------------------------------------
For the perspective matrix ``z_ndc = A + B / z_eye`` with ``A = (f+n)/(f-n)`` and
``B = 2fn/(f-n)``: an affine function of ``1/z_eye``. And ``1/z_eye`` (not ``z_eye``) is
what varies linearly across the screen, because a plane ``a x + b y + c z = d`` in eye
space, with ``x = -x_s z`` and ``y = -y_s z`` on the ray through screen point
``(x_s, y_s)``, gives ``1/z = -(a x_s + b y_s - c) / d``: linear in ``x_s, y_s``. So the
rasterizer interpolates ``depth_window`` linearly in window x, y (a plane through the three
window-space vertices) and that *is* the correct perspective depth.

Gambetta's worked example (seed 000): the segment from ``A = (-1, 0, 2)`` to
``B = (1, 0, 10)`` with its 3-D midpoint ``M = (0, 0, 6)``, projected with ``d = 1``,
lands at ``A'x = -1/2 = -0.5``, ``B'x = 1/10 = 0.1`` and ``M'x = 0``. Interpolating ``z``
linearly along the *screen* segment to ``x' = 0`` gives
``2 + (0 - (-0.5)) * (10 - 2) / (0.1 - (-0.5)) = 8.666``, but ``M`` is at ``z = 6``.
Interpolating ``1/z`` instead gives ``1/2 + 0.5 * (1/10 - 1/2) / 0.6 = 0.16666`` and
``1 / 0.16666 = 6``: exact. Linear-in-screen ``z`` would rank surfaces wrongly; linear
``1/z`` (hence linear window depth) never does.
``hsr.geometry.conventions.midpoint_depth_example()`` reproduces these numbers.

Attributes (colour, uv, normals) are interpolated *perspective-correctly*: screen-space
barycentrics ``l_i`` are turned into ``b_i = (l_i / w_i) / sum_j (l_j / w_j)``.

Depth values and ties
---------------------
The window depth at a pixel centre is evaluated from the *unsnapped* vertex positions
(as llvmpipe sets up its depth plane), clamped to the depth range (and, for a sliver
under 1/256 pixel high, to its corners' depths: snapping can make it cover a centre
where its plane, extrapolated across it, means nothing) and rounded to float32, then
compared with the float32 buffer value using the current depth function. Triangles
are processed in submission order, so ties are decided exactly as OpenGL decides them:
with ``less`` the first triangle drawn at a depth keeps the pixel, with ``lequal`` the
last one does. With the depth test disabled the last triangle drawn wins and the depth
buffer is not written (OpenGL writes depth only when the test is enabled).

Facing
------
A triangle's facing comes from the sign of its area in window space (y up), computed on
the clipped polygon as OpenGL does: counter-clockwise is front by default
(``glFrontFace(GL_CCW)``); ``glCullFace`` selects back, front or both.
"""

# Sub-pixel precision of the snapped window coordinates (8 bits, like llvmpipe).
SUBPIXEL_BITS = 8
SUBPIXEL_ONE = 1 << SUBPIXEL_BITS

# Window coordinates are kept within +-GUARD_BAND_PIXELS of the viewport by clipping,
# so snapped fixed-point coordinates (|x| < 2**29) keep edge-function products inside int64.
GUARD_BAND_PIXELS = 1 << 19


def midpoint_depth_example(a=(-1.0, 0.0, 2.0), b=(1.0, 0.0, 10.0), d=1.0):
    """Seed 000's worked example: depth of the segment AB at the screen position of its
    3-D midpoint, interpolated linearly in ``z`` (wrong) and in ``1/z`` (right).

    Returns ``(z_linear, z_from_inverse, z_true)``; for the defaults ``(8.666..., 6.0, 6.0)``.
    """
    ax, az = a[0] * d / a[2], a[2]
    bx, bz = b[0] * d / b[2], b[2]
    m = [(p + q) / 2.0 for p, q in zip(a, b)]
    mx = m[0] * d / m[2]
    t = (mx - ax) / (bx - ax)
    z_linear = az + t * (bz - az)
    z_from_inverse = 1.0 / (1.0 / az + t * (1.0 / bz - 1.0 / az))
    return z_linear, z_from_inverse, m[2]
