"""Latency of ``hsr view``'s API: the median time of ``GET /api/render`` for the bunny at
800 x 600 (JPEG, as while dragging, and PNG, as when still), measured from a client in
another process against a server started the way ``hsr view`` starts it, with the time
hsr.render itself takes in the same run as the peer.

    python benchmarks/bench_view.py [--requests 60] [--size 800x600] [--browser]

``--browser`` also drags the page in headless Chromium for three seconds and reports the
frames per second it shows (``--screenshot FILE`` saves the page afterwards). Runs on demand,
never as part of the test suite.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import time
import urllib.request

MODEL = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models",
                     "stanford-bunny.obj")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fetch(url):
    start = time.perf_counter()
    with urllib.request.urlopen(url, timeout=60) as r:
        r.read()
        stats = json.loads(r.headers["X-Hsr-Stats"])
    return 1e3 * (time.perf_counter() - start), stats


def browser_fps(base, seconds=3.0, screenshot=None):
    import shutil

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.support.ui import WebDriverWait

    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1400,900"):
        options.add_argument(arg)
    options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    try:
        driver.get(base + "/")
        WebDriverWait(driver, 60).until(
            lambda d: d.execute_script("return (window.hsr && window.hsr.frames) || 0") >= 1)
        driver.set_script_timeout(seconds + 30)
        got = driver.execute_async_script(
            f"window.hsr.drag({seconds}).then(arguments[arguments.length - 1])")
        if screenshot:
            time.sleep(1.0)  # the still view's PNG
            driver.save_screenshot(screenshot)
        return got["frames"] / got["seconds"]
    finally:
        driver.quit()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=60)
    parser.add_argument("--size", default="800x600")
    parser.add_argument("--browser", action="store_true")
    parser.add_argument("--screenshot", help="with --browser: save the page to this PNG")
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    port = free_port()
    server = subprocess.Popen([sys.executable, "-m", "hsr", "view", MODEL, "--no-browser",
                               "--port", str(port)], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    base = f"http://127.0.0.1:{port}"
    try:
        server.stdout.readline()  # "hsr view: URL": warm and listening
        deadline = time.time() + 60
        while time.time() < deadline:
            try:
                urllib.request.urlopen(base + "/api/options", timeout=5).read()
                break
            except OSError:
                time.sleep(0.1)
        rows = []
        for fmt in ("jpeg", "png"):
            times, render_ms, server_ms = [], [], []
            for k in range(args.requests + 5):
                ms, stats = fetch(f"{base}/api/render?w={w}&h={h}&format={fmt}&az={20 + k}")
                if k >= 5:  # the first few warm the paths
                    times.append(ms)
                    render_ms.append(stats["timings_ms"]["total"])
                    server_ms.append(stats["server_ms"])
            rows.append((fmt, statistics.median(times), statistics.median(server_ms),
                         statistics.median(render_ms)))
        fps = browser_fps(base, screenshot=args.screenshot) if args.browser else None
    finally:
        server.terminate()
        server.wait(30)
    print(f"bunny at {w}x{h}, {args.requests} requests each, medians (ms)\n")
    print("| format | /api/render, client | server: camera, render, buffer | hsr.render inside "
          "| API / render |")
    print("|---|---|---|---|---|")
    for fmt, total, server_ms, render in rows:
        print(f"| {fmt} | {total:.1f} | {server_ms:.1f} | {render:.1f} | {total / render:.2f} |")
    if fps is not None:
        print(f"\nbrowser (headless Chromium, 3 s drag at 60 moves/s): {fps:.1f} frames/s")


if __name__ == "__main__":
    main()
