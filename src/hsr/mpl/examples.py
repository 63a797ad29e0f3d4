"""The code of five matplotlib issues about mplot3d's occlusion, as their reporters wrote
it (``plt.show()`` left out; ``fig.gca(projection='3d')``, removed from matplotlib, written
as ``add_subplot``), with the projection as the one line that turns hsr on: each
``issue_N(plt, projection)`` returns ``(fig, ax)``, with ``projection`` "3d" for mplot3d's
own figure or "hsr3d". The tests, the docs' gallery and the guide page use them."""

import numpy as np


# --8<-- [start:29060]
def issue_29060(plt, projection):
    """matplotlib #29060: two plot_surface calls that cross."""
    fig = plt.figure()
    ax = fig.add_subplot(111, projection=projection)
    X, Y = np.meshgrid([-1, 1], [-1, 1])
    Z1 = np.zeros_like(X)
    Z2 = np.array([[-1, -1], [1, 1]])
    ax.plot_surface(X, Y, Z1)
    ax.plot_surface(X, Y, Z2)
    return fig, ax
# --8<-- [end:29060]


# --8<-- [start:23392]
def issue_23392(plt, projection, vertical_line_offset=0.253):
    """matplotlib #23392: scatter points just above a surface, all shown or all hidden."""
    def surface(x, y):
        return np.sin(x) + 0.5 * y * np.cos(x)

    x, y = np.meshgrid(np.linspace(-5, 5, 100), np.linspace(-5, 5, 100))
    fig = plt.figure(dpi=150)
    ax = fig.add_subplot(projection=projection)
    ax.set(xlabel='x', ylabel='y', zlim=(-3, 3), title=f'z offset = {vertical_line_offset}')
    ax.plot_surface(x, y, surface(x, y))
    a, b = np.meshgrid(np.linspace(-5, 5, 5), np.linspace(-5, 5, 100))
    ax.scatter3D(a, b, surface(a, b) + vertical_line_offset, color='red')
    return fig, ax
# --8<-- [end:23392]


# --8<-- [start:22165]
def issue_22165(plt, projection):
    """matplotlib #22165: a line through a surface."""
    V = np.linspace(-4, 4, 100)
    U = np.linspace(-4, 4, 100)
    U, V = np.meshgrid(U, V)
    X = U**2
    Y = V**2
    Z = U + 2 * V
    fig = plt.figure('1', figsize=(8, 7))
    ax = fig.add_subplot(111, projection=projection)
    ax.plot_surface(X, Y, Z, cmap=plt.cm.coolwarm)
    k = 10
    ax.plot(np.linspace(-2 - k, 1 + k, 10), np.linspace(-4 - k, 1 + k, 10),
            np.linspace(3 - k, 4 + k, 10), 'k')
    ax.set_xlabel('x')
    ax.set_ylabel('y')
    ax.set_zlabel('z')
    plt.tight_layout()
    return fig, ax
# --8<-- [end:22165]


# --8<-- [start:16071]
def issue_16071(plt, projection):
    """matplotlib #16071: a cylinder standing on a plane."""
    def data_for_cylinder_along_z(center_x, center_y, center_z, radius, height_z):
        z = np.linspace(0, height_z, 50)
        theta = np.linspace(0, 2 * np.pi, 50)
        theta_grid, z_grid = np.meshgrid(theta, z)
        x_grid = radius * np.cos(theta_grid) + center_x
        y_grid = radius * np.sin(theta_grid) + center_y
        z_grid = z_grid - height_z / 2 + center_z
        return x_grid, y_grid, z_grid

    fig = plt.figure(figsize=(10, 10))
    ax = fig.add_subplot(projection=projection)
    ax.view_init(90, 0)
    ax.set_xlabel('x')
    ax.set_ylabel('y')
    ax.set_zlabel('z')
    ax.set_xlim3d(-1, 1)
    ax.set_ylim3d(-1, 1)
    ax.set_zlim3d(-1, 1)
    yy, zz = np.meshgrid([-0.5, 0.5], [-0.5, 0.5])
    ax.plot_surface(0, yy, zz, color='yellow')
    r = 0.1
    Xc, Yc, Zc = data_for_cylinder_along_z(r, 0, 0, r, 1)
    ax.plot_surface(Xc, Yc, Zc)
    return fig, ax
# --8<-- [end:16071]


# --8<-- [start:9499]
def issue_9499(plt, projection):
    """matplotlib #9499: a patch drawn in front of a nearer one."""
    import matplotlib.patches as mpatches
    import matplotlib.path as mpath
    import mpl_toolkits.mplot3d.art3d as art3d
    from matplotlib.patches import Rectangle

    fig = plt.figure()
    ax = fig.add_subplot(projection=projection)
    ax.set_xlim(-16, 16)
    ax.set_ylim(-16, 16)
    ax.set_zlim(-16, 16)
    for depth in [0.]:
        theta = np.linspace(-5 * np.pi, 5 * np.pi, 1000)
        y = theta
        z = 4 * np.cos(0.2 * theta) * np.sin(0.4 * 8 * theta)
        points = np.array([y, z]).T
        patch = mpatches.PathPatch(mpath.Path(points))
        ax.add_patch(patch)
        art3d.pathpatch_2d_to_3d(patch, z=depth, zdir='x')
    for depth in range(6, 7):
        ret = Rectangle((0 - 5, 0 - 5), 5 * 2, 5 * 2,
                        facecolor=(depth / 10, depth / 10, depth / 10),
                        edgecolor=(0., 0., 0.), alpha=1.)
        ax.add_patch(ret)
        art3d.pathpatch_2d_to_3d(ret, z=depth, zdir='x')
    return fig, ax
# --8<-- [end:9499]


CASES = {"29060": issue_29060, "23392": issue_23392, "22165": issue_22165,
         "16071": issue_16071, "9499": issue_9499}
