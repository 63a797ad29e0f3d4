"""Every fenced Python block and every ``hsr`` command of the README runs, in document
order, in a temporary folder beside ``../shared`` (so the README's ``../shared/models``
paths resolve), as a reader would run them one after another. Python blocks share one
namespace (a later block uses the ``mesh`` or ``scene`` of an earlier one, as in a
notebook). Only installing (``pip``), the test suite itself and the on-demand benchmarks
are not run; anything else that is not an ``hsr`` command fails the test, so a new kind
of example has to be added here on purpose. ``sh`` blocks are commands for a cluster
(``dask scheduler`` on another machine) or that keep running (``hsr view``'s server, and
``curl`` calls against it); tests/test_batch.py runs ``hsr batch --scheduler`` against a
scheduler and a worker it starts, tests/test_viewer.py the viewer's API and page."""

import os
import re
import shlex

import pytest

from conftest import MODELS_DIR
from hsr.cli import main

README = os.path.join(os.path.dirname(__file__), "..", "README.md")
NOT_RUN = (("pip",), ("python", "-m", "pytest"), ("python", "benchmarks/"))


def fenced_blocks():
    text = open(README).read()
    return [(lang, body) for lang, body in re.findall(r"```(\w*)\n(.*?)```", text, re.S)
            if lang in ("python", "bash")]


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
    monkeypatch.chdir(work)
    return work


def test_readme_runs_as_written(beside_shared, capsys):
    namespace, ran_python, ran_hsr = {"__name__": "__main__"}, 0, []
    for lang, body in fenced_blocks():
        if lang == "python":
            exec(compile(body, "README.md", "exec"), namespace)
            ran_python += 1
            continue
        for tokens in commands(body):
            if not tokens or is_not_run(tokens):
                continue
            assert tokens[0] == "hsr", f"README command that this test cannot run: {tokens}"
            code = main(tokens[1:])
            err = capsys.readouterr().err
            assert code == 0, f"{shlex.join(tokens)} -> exit {code}: {err}"
            ran_hsr.append(tokens)
    print(f"ran {ran_python} Python blocks and {len(ran_hsr)} hsr commands")
    assert ran_python >= 6 and len(ran_hsr) >= 25
    # What the examples say they write is there.
    for name in ("bunny.png", "parts.glb", "transforms.json", "lines.svg", "cubes.png",
                 "normals.exr", "eye.exr", "spot_003.png", "report.html", "compare.png",
                 "views/manifest.json", "stores/spot.zarr/zarr.json",
                 "from_python/spot/ids/0005.npy"):
        assert (beside_shared / name).stat().st_size > 0, name
    assert namespace["result"].rendered == 6  # the batch example's guarded main ran
    assert namespace["names"] == ["left", "right", "ball"]
    assert namespace["seen"] == {"left", "right", "ball"}


def test_every_block_is_seen():
    """The block finder sees the README's blocks (a changed fence style would silently
    run nothing)."""
    blocks = fenced_blocks()
    assert sum(lang == "python" for lang, _ in blocks) >= 6
    assert sum(1 for lang, body in blocks if lang == "bash" for _ in commands(body)) >= 30
