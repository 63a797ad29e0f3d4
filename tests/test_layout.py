"""The package layout follows the data path (issue: one folder per stage): imports only go
down it, and no module imports another that imports it back (directly or through others,
lazily or not). Read from the source with ``ast``, so a lazy import inside a function
counts as much as one at the top."""

import ast
import os

SRC = os.path.join(os.path.dirname(__file__), "..", "src", "hsr")

# Stage of each package along the data path; modules at the root are the public face
# (render, cli) or helpers every stage may use (errors, parallel, choices).
STAGES = {"errors": 0, "parallel": 0, "choices": 0, "scene": 1, "geometry": 2, "raster": 3,
          "algorithms": 4, "appearance": 5, "lines": 5, "render": 6, "__init__": 6,
          "explain": 7, "batch": 7, "visibility": 7, "viewer": 7, "mpl": 7, "cli": 8,
          "__main__": 9}


def _modules():
    out = {}
    for folder, _, files in os.walk(SRC):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                rel = os.path.relpath(path, SRC)[:-3].replace(os.sep, ".")
                out["hsr" if rel == "__init__" else "hsr." + rel.removesuffix(".__init__")] = path
    return out


def _imports(module, path, known):
    package = module if path.endswith("__init__.py") else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(open(path).read())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not target.startswith("hsr"):
                continue
            for alias in node.names:  # "from . import x" may name a module
                sub = f"{target}.{alias.name}"
                found.add(sub if sub in known else target)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("hsr"))
    return {t for t in found if t in known and t != module}


def _graph():
    known = _modules()
    return {m: _imports(m, p, known) for m, p in known.items()}


def _stage(module):
    parts = module.split(".")
    return STAGES["__init__" if len(parts) == 1 else parts[1]]


def test_every_package_is_a_known_stage():
    for module in _graph():
        assert module == "hsr" or module.split(".")[1] in STAGES, module


def test_imports_only_go_down_the_data_path():
    wrong = [(m, t) for m, targets in _graph().items() for t in targets
             if _stage(t) > _stage(m)
             and not (m == "hsr" and t.split(".")[1] not in ("explain", "cli"))]
    assert not wrong, f"imports of a later stage: {wrong}"


def test_no_import_cycles():
    graph = _graph()
    state = {}

    def visit(m, path):
        state[m] = "open"
        for t in graph[m]:
            if state.get(t) == "open":
                raise AssertionError("import cycle: " + " -> ".join(path + [t]))
            if t not in state:
                visit(t, path + [t])
        state[m] = "done"

    for module in graph:
        if module not in state:
            visit(module, [module])


# The ray core's modules, top first: each may import only those before it (issue #66).
RAY_CORE = ["layout", "triangle", "boxes", "stack", "collapse", "sah", "ranking", "hits",
            "walk", "packets", "choice"]


def test_the_ray_core_imports_only_down_its_list():
    graph = _graph()
    package = "hsr.algorithms.bvh"
    present = sorted(m.rsplit(".", 1)[1] for m in graph if m.startswith(package + "."))
    assert present == sorted(RAY_CORE), "a ray-core module missing from RAY_CORE or gone"
    wrong = [(m, t) for m in graph if m.startswith(package + ".")
             for t in graph[m] if t.startswith(package + ".")
             and RAY_CORE.index(t.rsplit(".", 1)[1]) >= RAY_CORE.index(m.rsplit(".", 1)[1])]
    assert not wrong, f"ray-core imports that do not go down its list: {wrong}"


def _private_imports(path):
    """(module, name) of every private name imported from an hsr module in ``path``."""
    found = []
    for node in ast.walk(ast.parse(open(path).read())):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith(
                "hsr")):
            found += [(node.module, a.name) for a in node.names
                      if a.name.startswith("_") and not a.name.startswith("__")]
    return found


def test_no_module_imports_a_private_name():
    """What another module uses is public in its own (the ray core first kept this rule,
    issue #66; every module now does)."""
    modules = _modules()
    assert len([m for m in modules if m.startswith("hsr.algorithms.bvh")]) > 10
    wrong = {m: found for m, path in modules.items() if (found := _private_imports(path))}
    assert not wrong, f"private names imported: {wrong}"


def test_the_private_import_check_can_fail(tmp_path):
    path = tmp_path / "m.py"
    path.write_text("from .walk import _secret, public\nfrom hsr.x import __all__\n")
    assert _private_imports(str(path)) == [("walk", "_secret")]


def test_the_layout_test_sees_lazy_imports():
    """The checker must be able to fail: a lazy import inside a function is found."""
    graph = _graph()
    assert "hsr.explain.compare" in graph["hsr.explain.views"]  # imported inside functions
    assert "hsr.scene.mesh" in graph["hsr.geometry.stage"]


def test_architecture_tree_names_every_module_and_only_files_that_exist():
    page = open(os.path.join(SRC, "..", "..", "docs", "architecture.md")).read()
    section = page.split("## The data path and the source tree", 1)[1].split("\n## ", 1)[0]
    tree = section.split("src/hsr/", 1)[1].split("```", 1)[0]
    folders, named = {}, []  # indent -> the folder opened at that indent
    for line in tree.splitlines():
        if not line.strip():
            continue
        words = line.split()
        indent = len(line) - len(line.lstrip())
        inside = [folders[i] for i in sorted(folders) if i < indent]
        if words[0].endswith("/"):
            folders = {i: f for i, f in folders.items() if i < indent}
            folders[indent] = words[0]
            continue
        for word in words:
            if not word.endswith(".py"):
                break
            named.append(os.path.join(*inside, word))
    assert len(named) > 30
    missing = [n for n in named if not os.path.isfile(os.path.join(SRC, n))]
    assert not missing, f"docs/architecture.md names files that do not exist: {missing}"
    listed = {os.path.normpath(n) for n in named}
    actual = {os.path.relpath(p, SRC) for p in _modules().values()}
    unlisted = sorted(a for a in actual - listed if not a.endswith("__init__.py"))
    assert not unlisted, f"modules missing from the tree in docs/architecture.md: {unlisted}"


def test_public_entry_points_document_what_they_raise():
    import inspect

    import hsr
    from hsr.cli import main
    from hsr.explain import explain
    from hsr.explain.compare import compare_algorithms
    from hsr.explain.report import write_report

    entry_points = [hsr.load, hsr.render, hsr.Mesh, hsr.Scene.add, hsr.Instance,
                    hsr.Camera.look_at, hsr.Camera.orthographic, hsr.Camera.frame,
                    hsr.Camera.validate, hsr.RenderState, hsr.bsp.build, hsr.raycast.build,
                    hsr.hidden_lines, hsr.write_lines_svg, hsr.Frame.save, hsr.Frame.save_depth,
                    hsr.Frame.save_ids, explain, compare_algorithms, write_report,
                    hsr.scenes.get, hsr.Fog, hsr.HiddenLine, hsr.Look, main,
                    hsr.load_scene, hsr.Camera.from_opencv, hsr.Camera.from_matrices,
                    hsr.Camera.to_opencv, hsr.views.default, hsr.first_look, hsr.best_view,
                    hsr.views.framed,
                    hsr.views.orbit, hsr.views.sphere, hsr.views.hemisphere,
                    hsr.read_transforms, hsr.write_transforms, hsr.read_colmap,
                    hsr.batch.render_views, hsr.batch.parse_views]
    silent = [f.__qualname__ for f in entry_points
              if not any(w in (inspect.getdoc(f) or "") for w in ("Raises", "Raise "))]
    assert not silent, f"public entry points that do not say what they raise: {silent}"


