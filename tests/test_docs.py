"""The documentation runs as written, and builds.

Every fenced Python block and every ``hsr`` command of the README and of each page under
``docs/`` runs, page by page in document order, each page in a fresh folder beside
``../shared`` (so the ``../shared/models`` paths resolve) with a namespace of its own: a
page's later blocks use what its earlier ones made, as a reader running it top to
bottom would, but no page leans on another. Only installing (``pip``), the test suite,
the linters, the docs build and the on-demand benchmarks are not run; anything else that
is not an ``hsr`` command fails the test, so a new kind of example is added here on
purpose. ``sh`` blocks are commands for a cluster or that keep running (``hsr view``,
``curl`` against it); tests/test_batch.py and tests/test_viewer.py run those paths.

Then the site is built with ``mkdocs build --strict`` (broken links, missing pages,
images or snippets, and docstring problems fail it), and its API reference must name
every public function and class of ``hsr`` and of the sub-packages users import.
"""

import gzip
import os
import re
import shlex
import subprocess
import sys

import pytest

from conftest import MODELS_DIR
from hsr.cli import main

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
DOCS = os.path.join(ROOT, "docs")
NOT_RUN = (("pip",), ("python", "-m", "pytest"), ("python", "benchmarks/"),
           ("python", "docs/"), ("ruff",), ("mypy",), ("mkdocs",))
# Pages that are not prose with examples: the changelog is a snippet of CHANGELOG.md.
SKIPPED_PAGES = ("changelog.md",)


def pages() -> list:
    found = ["README.md"]
    for folder, _dirs, files in sorted(os.walk(DOCS)):
        for name in sorted(files):
            if name.endswith(".md") and name not in SKIPPED_PAGES:
                found.append(os.path.relpath(os.path.join(folder, name), ROOT))
    return found


def fenced_blocks(page: str):
    text = open(os.path.join(ROOT, page)).read()
    return [(lang, expand_snippets(body))
            for lang, body in re.findall(r"```(\w*)\n(.*?)```", text, re.S)
            if lang in ("python", "bash")]


def expand_snippets(body: str) -> str:
    """A block's ``--8<-- "path:section"`` lines replaced by that section of the file, as
    pymdownx.snippets does when the site is built (so the included code runs here too)."""
    def section(match):
        path, _, name = match.group(1).partition(":")
        text = open(os.path.join(ROOT, path)).read()
        if not name:
            return text
        start = text.index(f"--8<-- [start:{name}]")
        start = text.index("\n", start) + 1
        return text[start:text.index(f"# --8<-- [end:{name}]", start)]

    return re.sub(r'^--8<-- "([^"]+)"$', section, body, flags=re.M)


def commands(body: str):
    """The commands of a bash block: continuation lines joined, comments dropped, each
    ``a && b`` as two."""
    for line in body.replace("\\\n", " ").splitlines():
        tokens = shlex.split(line, comments=True)
        while tokens:
            cut = tokens.index("&&") if "&&" in tokens else len(tokens)
            yield tokens[:cut]
            tokens = tokens[cut + 1:]


def is_not_run(tokens) -> bool:
    if tokens and "=" in tokens[0] and not tokens[0].startswith("-"):  # VAR=value cmd ...
        tokens = tokens[1:]
    return any(all(t.startswith(p) if p.endswith("/") else t == p
                   for t, p in zip(tokens, prefix)) and len(tokens) >= len(prefix)
               for prefix in NOT_RUN)


@pytest.fixture
def beside_shared(tmp_path, monkeypatch, models_dir):
    work = tmp_path / "work"
    work.mkdir()
    (tmp_path / "shared").symlink_to(os.path.dirname(MODELS_DIR))
    # The CAD page's part: a real STEP file the tests keep (tests/data/cad).
    with gzip.open(os.path.join(ROOT, "tests", "data", "cad", "as1-oc-214.stp.gz"), "rb") as src:
        (work / "as1-oc-214.stp").write_bytes(src.read())
    monkeypatch.chdir(work)
    return work


# A quoted output: ``print(...)  # prints TEXT``, where ``...`` in TEXT stands for any text
# (a time, say); the page's claim is checked against what the call prints.
PRINTS = re.compile(r"^(\s*)print\((.*)\)\s*# prints (.*)$", re.M)


def _check_print(*values, expected: str, where: str) -> None:
    printed = " ".join(str(v) for v in values)
    pattern = ".*".join(re.escape(part) for part in expected.strip().split("..."))
    assert re.fullmatch(pattern, printed), f"{where}: prints {printed!r}, the page says " \
                                           f"{expected.strip()!r}"
    print(printed)


def checked_prints(body: str, page: str) -> str:
    """``body`` with each ``print(...)  # prints TEXT`` line made a check of TEXT."""
    return PRINTS.sub(lambda m: f"{m.group(1)}_check_print({m.group(2)}, expected="
                                f"{m.group(3)!r}, where={page!r})", body)


def run_page(page: str, capsys) -> tuple:
    """Run a page's blocks in order; (namespace, Python blocks run, hsr commands run)."""
    namespace = {"__name__": "__main__", "_check_print": _check_print}
    ran_python, ran_hsr = 0, 0
    for lang, body in fenced_blocks(page):
        if lang == "python":
            exec(compile(checked_prints(body, page), page, "exec"), namespace)
            ran_python += 1
            continue
        for tokens in commands(body):
            if not tokens or is_not_run(tokens):
                continue
            if tokens[0] == "vpype":  # the plugin, through vpype's own command line
                import vpype_cli

                vpype_cli.execute(shlex.join(tokens[1:]))
                ran_hsr += 1
                continue
            assert tokens[0] == "hsr", f"{page}: a command this test cannot run: {tokens}"
            code = main(tokens[1:])
            err = capsys.readouterr().err
            assert code == 0, f"{page}: {shlex.join(tokens)} -> exit {code}: {err}"
            ran_hsr += 1
    return namespace, ran_python, ran_hsr


# What some pages say they write, or compute, checked after they ran.
WRITES = {
    "README.md": ("cubes.png", "bunny.png"),
    "docs/guide/rendering.md": ("bunny.png", "depth.npy", "ids.npy"),
    "docs/guide/models.md": ("parts.glb",),
    "docs/guide/cameras.md": ("transforms.json",),
    "docs/guide/appearance.md": ("lines.svg", "head.png", "glass_exact.png"),
    "docs/guide/batch.md": ("views/manifest.json", "stores/spot.zarr/zarr.json",
                            "from_python/spot/ids/0005.npy", "bunny.zarr/zarr.json",
                            "bunny-views/bunny/color/0005.png"),
    "docs/guide/explain.md": ("report.html", "painter.gif", "overdraw.png"),
    "docs/guide/cli.md": ("normals.exr", "eye.exr", "spot_003.png", "from_nerf.png"),
    "docs/guide/algorithms.md": ("compare.png", "cyclic.svg"),
    "docs/guide/prune.md": ("spot-visible.glb", "housing-visible.glb"),
    "docs/guide/visibility.md": ("spot_faces.npz", "spot_vertices.csv"),
    "docs/guide/matplotlib.md": ("crossing.pdf", "occluded.svg"),
    "docs/guide/lines.md": ("spot-lines.svg", "fandisk.svg", "crossing.svg", "spot-a4.svg",
                            "spot-vpype.svg", "bunny-a4.svg", "as1.svg"),
}


@pytest.mark.parametrize("page", pages())
def test_page_runs_as_written(page, beside_shared, capsys):
    namespace, ran_python, ran_hsr = run_page(page, capsys)
    print(f"{page}: ran {ran_python} Python blocks and {ran_hsr} hsr commands")
    for name in WRITES.get(page, ()):
        assert (beside_shared / name).stat().st_size > 0, f"{page} should write {name}"
    if page == "docs/guide/models.md":
        assert namespace["names"] == ["left", "right", "ball"]
        assert namespace["seen"] == {"left", "right", "ball"}
    if page == "docs/guide/batch.md":
        assert namespace["result"].rendered == 6  # the guarded main ran


def test_blocks_are_seen():
    """The block finder sees the pages' blocks (a changed fence style would silently run
    nothing): the guide alone has dozens of Python blocks and commands."""
    blocks = [b for page in pages() for b in fenced_blocks(page)]
    assert sum(lang == "python" for lang, _ in blocks) >= 15
    assert sum(1 for lang, body in blocks if lang == "bash" for _ in commands(body)) >= 40
    for page in ("README.md", "docs/guide/rendering.md", "docs/guide/visibility.md"):
        assert fenced_blocks(page), page


def public_names() -> set:
    """Every public function and class a user imports: ``hsr.__all__`` (its modules
    opened up) and the ``__all__`` of hsr.visibility and hsr.batch, hsr.views' and
    hsr.scenes' functions."""
    import inspect

    import hsr

    names = set()
    for owner in (hsr, hsr.visibility, hsr.batch, hsr.views, hsr.scenes):
        listed = getattr(owner, "__all__", None) or [
            n for n, v in vars(owner).items() if not n.startswith("_")
            and inspect.isfunction(v) and v.__module__ == owner.__name__]
        for name in listed:
            value = getattr(owner, name)
            if inspect.ismodule(value):
                continue
            if inspect.isclass(value) or callable(value):
                names.add(name)
    return names


def test_site_builds_strictly_and_names_the_api(tmp_path, models_dir):
    # (models_dir: the gallery draws the shared models; without them this skips as the
    # other tests that read them do, and fails in CI)
    pytest.importorskip("mkdocs")  # the test extra installs it; CI fails without it
    site = tmp_path / "site"
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d",
                           str(site)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    ids = set()
    for folder, _dirs, files in os.walk(site / "api"):
        for name in files:
            if name.endswith(".html"):
                ids |= set(re.findall(r'id="(hsr\.[\w.]+)"', open(os.path.join(folder,
                                                                                 name)).read()))
    documented = {i.rsplit(".", 1)[-1] for i in ids}
    missing = sorted(public_names() - documented)
    assert not missing, f"public names without an API entry: {missing}"
    for name in ("render", "from_opencv", "RayScene", "face_visibility", "prune",
                 "render_views", "visible_vertices"):
        assert name in documented, name
    for picture in ("algorithms.png", "models.png", "prune.png"):
        assert (site / "gallery" / picture).stat().st_size > 0, picture


def test_quoted_outputs_are_checked_and_can_fail():
    """A page's ``# prints`` claim that the code does not print fails the page."""
    namespace = {"_check_print": _check_print}
    exec(checked_prints("print(6 * 7)  # prints 42\nprint('t', 1.25)  # prints t ...\n",
                        "page.md"), namespace)
    with pytest.raises(AssertionError, match="the page says '332 -> 12'"):
        exec(checked_prints("print(1292, '->', 12)  # prints 332 -> 12\n", "page.md"),
             namespace)


def test_the_command_line_page_lists_every_built_in_scene():
    """cli.md's --scene list missed two scenes."""
    from hsr.scene.builtin import SCENES

    text = open(os.path.join(DOCS, "guide", "cli.md")).read()
    listed = re.search(r"`--scene NAME` \(`([^`]*)`\)", text)
    assert listed and listed.group(1).split() == list(SCENES)
