"""hsr.mpl against mplot3d's own draw of the same figure, in the same run (Agg, and the
PDF each writes):

    python benchmarks/bench_mpl.py [--repeat 5]

Cases (the issue's): an N x N plot_surface (rstride = cstride = 1: (N - 1)^2 quads) with
1,000 scatter points on it and a 1,000-segment line through it, for N = 100 and 300 (the
fastest draw of each, in blocks that alternate over three rounds); then the SVG and PDF
sizes of the five matplotlib issues' figures (hsr.mpl.examples).
"""

from __future__ import annotations

import argparse
import io
import os
import sys

import numpy as np
from bench_regions import cpu_name

from common import timings


def figure(n: int, projection: str):
    import matplotlib.pyplot as plt

    x, y = np.meshgrid(np.linspace(-3, 3, n), np.linspace(-3, 3, n))
    z = np.sin(x) * np.cos(y)
    fig = plt.figure(figsize=(6.4, 4.8), dpi=100)
    ax = fig.add_subplot(projection=projection)
    ax.plot_surface(x, y, z, rstride=1, cstride=1, cmap="viridis")
    rng = np.random.default_rng(0)
    px, py = rng.uniform(-3, 3, (2, 1000))
    ax.scatter(px, py, np.sin(px) * np.cos(py) + 0.05, s=4, color="red")
    t = np.linspace(0, 1, 1001)
    ax.plot(6 * t - 3, 3 * np.sin(6 * t), 2 * t - 1, color="black")
    return fig


def main(argv=None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import hsr.mpl  # noqa: F401  (registers "hsr3d")

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("sizes", nargs="*", type=int, default=[100, 300])
    args = parser.parse_args(argv)
    print(f"CPU: {cpu_name()}, {os.cpu_count()} cores; matplotlib {matplotlib.__version__}")
    print(f"{'surface':>10} {'quads':>7} {'mplot3d ms':>10} {'hsr ms':>8} {'x mplot3d':>9} "
          f"{'mplot3d PDF':>11} {'hsr PDF':>9}")
    for n in args.sizes:
        figs = {p: figure(n, p) for p in ("3d", "hsr3d")}
        # Blocks alternate over three rounds: both draws see the same machine load.
        (t3, _), (th, _) = timings([figs["3d"].canvas.draw, figs["hsr3d"].canvas.draw],
                                   args.repeat, rounds=3)
        size = {}
        for p, fig in figs.items():
            buf = io.BytesIO()
            fig.savefig(buf, format="pdf")
            size[p] = len(buf.getvalue())
        print(f"{f'{n} x {n}':>10} {(n - 1) ** 2:7d} {t3:10.0f} {th:8.0f} {th / t3:9.2f} "
              f"{size['3d'] / 1e6:9.2f}MB {size['hsr3d'] / 1e6:7.2f}MB", flush=True)
        plt.close("all")
    from hsr.mpl.examples import CASES

    print(f"{'issue':>8} {'mplot3d SVG':>12} {'hsr SVG':>9} {'mplot3d PDF':>12} {'hsr PDF':>9}")
    for name, case in CASES.items():
        size = {}
        for p in ("3d", "hsr3d"):
            fig, _ = case(plt, p)
            for fmt in ("svg", "pdf"):
                buf = io.BytesIO()
                # No date: the sizes compare drawings, not time stamps.
                fig.savefig(buf, format=fmt, metadata={"Date": None} if fmt == "svg"
                            else {"CreationDate": None})
                size[p, fmt] = len(buf.getvalue()) / 1e3
            plt.close(fig)
        print(f"{'#' + name:>8} {size['3d', 'svg']:10.1f}kB {size['hsr3d', 'svg']:7.1f}kB "
              f"{size['3d', 'pdf']:10.1f}kB {size['hsr3d', 'pdf']:7.1f}kB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
