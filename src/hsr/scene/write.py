"""Writing a scene back to a mesh file, face order kept: Wavefront OBJ (+ .mtl, texture
coordinates, normals, the texture copied beside it), PLY (one mesh, face colours) and
binary glTF (one node per instance with its transform and name, shared meshes shared,
base colour texture and factor, vertex colours). ``hsr.load`` / ``hsr.load_scene`` read
each back to the same faces in the same order.

OBJ and PLY have no transforms: instances are written in world space (each world
triangle exactly as rendered, so culling and winding are unchanged). glTF has one base
colour factor per material: a textured mesh whose faces carry several colours keeps the
first.
"""

from __future__ import annotations

import os
import shutil

import numpy as np

from ..errors import OutputError
from .files import check_output
from .mesh import Scene, SceneLike, as_scene, normal_matrix
from .outputs import OutputPlan, staged

__all__ = ["write_mesh", "planned_files", "check_new", "MESH_FORMATS"]

MESH_FORMATS = (".obj", ".ply", ".glb")


def write_mesh(scene: SceneLike, path: str | os.PathLike, overwrite: bool = False) -> list:
    """Write ``scene`` (a Scene, Mesh, ...) to ``path`` (.obj, .ply or .glb). Returns the
    files written (an OBJ's .mtl and texture too). A file that exists already (the
    model's, or one of an OBJ's .mtl and textures) is replaced only with ``overwrite``.
    Raises :class:`~hsr.errors.OutputError` for another extension, a folder that cannot
    be written, a file that exists without ``overwrite``, or (even with it) a file the
    scene was read from (:attr:`~hsr.Mesh.sources`)."""
    scene = as_scene(scene)
    path = check_output(os.fspath(path), MESH_FORMATS)
    planned = planned_files(scene, path)
    if not overwrite:
        check_new(planned)
    # Never over a file the scene was read from, even with overwrite (hsr.scene.outputs).
    plan = OutputPlan([("a file the scene was read from", p) for p in scene.sources()])
    for p in planned:
        plan.add("path", p)
    ext = os.path.splitext(path)[1].lower()
    try:
        with staged(path) as tmp:  # every file written whole, then renamed into place
            if ext == ".obj":
                names = [os.path.basename(p) for p in _write_obj(scene, tmp)]
                return [os.path.join(os.path.dirname(path), n) for n in names]
            if ext == ".ply":
                _trimesh_world(scene).export(tmp, file_type="ply")
            else:
                _write_glb(scene, tmp)
        return [path]
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None


def planned_files(scene, path) -> list:
    """The files :func:`write_mesh` writes for ``scene`` at ``path``: the model, and for
    an OBJ its .mtl and the textures beside it."""
    path = os.fspath(path)
    if os.path.splitext(path)[1].lower() != ".obj":
        return [path]
    folder, stem = os.path.dirname(path) or ".", os.path.splitext(os.path.basename(path))[0]
    names = _texture_names(as_scene(scene), stem)
    return [path, os.path.join(folder, f"{stem}.mtl")] + [os.path.join(folder, n)
                                                          for n in names.values()]


def check_new(paths, flag: str = "overwrite=True") -> None:
    """Raise :class:`OutputError` for the first of ``paths`` that exists (anything at
    all: a file, a folder, a link), naming ``flag`` as the way to replace it."""
    for p in paths:
        if os.path.lexists(p):
            raise OutputError(f"{p} exists; hsr replaces it only when asked ({flag})")


def _texture_names(scene: Scene, stem: str) -> dict:
    """Texture (a path, or the id of an array) -> its file name beside an OBJ named
    ``stem``, in the order the instances first use them."""
    names: dict = {}
    for inst in scene.instances:
        texture = inst.mesh.texture
        if texture is None:
            continue
        key = texture if isinstance(texture, str) else id(texture)
        if key not in names:
            ext = os.path.splitext(texture)[1] if isinstance(texture, str) else ".png"
            names[key] = f"{stem}_{len(names)}{ext}"
    return names


def _world(inst):
    """World-space positions and corner normals of an instance."""
    m = inst.model
    positions = inst.mesh.positions @ m[:3, :3].T + m[:3, 3]
    normals = inst.mesh.corner_normals
    if normals is not None:
        normals = normals @ normal_matrix(m).T
        normals = normals / np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True),
                                       1e-300)
    return positions, normals


def _write_obj(scene: Scene, path: str) -> list:
    """One OBJ for the scene (an ``o`` per instance), a .mtl with a material per (texture,
    colour) pair, the textures copied (or saved as PNG) beside it."""
    folder, stem = os.path.dirname(path) or ".", os.path.splitext(os.path.basename(path))[0]
    written, materials, textures = [path], {}, {}  # type: list[str], dict, dict
    names = _texture_names(scene, stem)
    lines, base_v, base_vt, base_vn = [f"mtllib {stem}.mtl\n"], 1, 1, 1
    for inst in scene.instances:
        mesh = inst.mesh
        positions, normals = _world(inst)
        tex_name = _texture_file(mesh.texture, folder, names, textures, written)
        lines.append(f"o {_token(inst.name)}\n")
        lines += [f"v {x!r} {y!r} {z!r}\n" for x, y, z in positions.tolist()]
        if mesh.corner_uv is not None:
            lines += [f"vt {u!r} {v!r}\n" for u, v in mesh.corner_uv.reshape(-1, 2).tolist()]
        if normals is not None:
            lines += [f"vn {x!r} {y!r} {z!r}\n" for x, y, z in normals.reshape(-1, 3).tolist()]
        colors = mesh.face_colors
        current = None
        for f, (a, b, c) in enumerate(mesh.faces.tolist()):
            key = (tex_name, None if colors is None else tuple(colors[f].tolist()))
            if key != (None, None) and key != current:
                if key not in materials:
                    materials[key] = f"m{len(materials)}"
                lines.append(f"usemtl {materials[key]}\n")
                current = key
            corners = []
            for k, v in enumerate((a, b, c)):
                t = base_vt + 3 * f + k if mesh.corner_uv is not None else None
                n = base_vn + 3 * f + k if normals is not None else None
                corners.append(f"{base_v + v}" + ("" if t is None and n is None else
                                                  f"/{'' if t is None else t}"
                                                  + ("" if n is None else f"/{n}")))
            lines.append("f " + " ".join(corners) + "\n")
        base_v += len(positions)
        base_vt += 0 if mesh.corner_uv is None else 3 * mesh.n_faces
        base_vn += 0 if normals is None else 3 * mesh.n_faces
    with open(path, "w", encoding="utf-8") as handle:
        handle.writelines(lines)
    mtl = os.path.join(folder, f"{stem}.mtl")
    with open(mtl, "w", encoding="utf-8") as handle:
        for (tex_name, color), name in materials.items():
            rgb = (255, 255, 255) if color is None else color
            handle.write(f"newmtl {name}\nKd " + " ".join(f"{c / 255:.9f}" for c in rgb)
                         + "\n" + (f"map_Kd {tex_name}\n" if tex_name else "") + "\n")
    written.insert(1, mtl)
    return written


def _token(name: str | None) -> str:
    return "_".join(str(name).split()) or "object"


def _texture_file(texture, folder, names, textures, written):
    """The file name (beside the OBJ) of a mesh's texture, copied or saved once."""
    if texture is None:
        return None
    key = texture if isinstance(texture, str) else id(texture)
    if key not in textures:
        name = names[key]
        if isinstance(texture, str):
            shutil.copyfile(texture, os.path.join(folder, name))
        else:
            from PIL import Image

            Image.fromarray(np.asarray(texture, dtype=np.uint8)).save(os.path.join(folder,
                                                                                   name))
        textures[key] = name
        written.append(os.path.join(folder, name))
    return textures[key]


def _trimesh_world(scene: Scene):
    """All instances as one trimesh in world space (PLY): faces in order, face colours
    where the scene has them."""
    import trimesh

    positions, faces, colors, base = [], [], [], 0
    has_colors = any(i.mesh.face_colors is not None for i in scene.instances)
    for inst in scene.instances:
        world, _ = _world(inst)
        positions.append(world)
        faces.append(inst.mesh.faces + base)
        base += len(world)
        if has_colors:
            fc = inst.mesh.face_colors
            colors.append(np.full((inst.mesh.n_faces, 3), 204, np.uint8) if fc is None else fc)
    return trimesh.Trimesh(np.concatenate(positions), np.concatenate(faces),
                           face_colors=np.concatenate(colors) if has_colors else None,
                           process=False, validate=False)


def _write_glb(scene: Scene, path: str) -> None:
    """One node per instance (its name and model matrix), one glTF mesh per hsr mesh."""
    import trimesh

    out = trimesh.Scene()
    geometry: dict = {}
    for k, inst in enumerate(scene.instances):
        key = id(inst.mesh)
        if key not in geometry:  # in the scene's geometry, not yet on a node
            geometry[key] = f"mesh{len(geometry)}"
            out.geometry[geometry[key]] = _trimesh_mesh(inst.mesh)
        node = f"{inst.name}" if inst.name not in out.graph.nodes else f"{inst.name}.{k}"
        out.graph.update(frame_to=node, frame_from=out.graph.base_frame,
                         matrix=inst.model, geometry=geometry[key])
    data = out.export(file_type="glb")
    with open(path, "wb") as handle:
        handle.write(data)


def _trimesh_mesh(mesh):
    """A trimesh of one hsr mesh in model space. Corner attributes (texture coordinates,
    normals, vertex colours) need a vertex per corner in glTF; without them the vertices
    are shared as in the mesh."""
    import trimesh

    per_corner = any(a is not None for a in (mesh.corner_uv, mesh.corner_normals,
                                             mesh.corner_colors))
    if per_corner:
        vertices = mesh.positions[mesh.faces].reshape(-1, 3)
        faces = np.arange(3 * mesh.n_faces).reshape(-1, 3)
    else:
        vertices, faces = mesh.positions, mesh.faces
    normals = None if mesh.corner_normals is None else mesh.corner_normals.reshape(-1, 3)
    out = trimesh.Trimesh(vertices, faces, vertex_normals=normals, process=False,
                          validate=False)
    factor = None if mesh.face_colors is None else mesh.face_colors[0]
    if mesh.texture is not None and mesh.corner_uv is not None:
        from PIL import Image

        image = (Image.open(mesh.texture) if isinstance(mesh.texture, str)
                 else Image.fromarray(np.asarray(mesh.texture, dtype=np.uint8)))
        material = trimesh.visual.material.PBRMaterial(
            baseColorTexture=image.convert("RGB"),
            baseColorFactor=(255, 255, 255, 255) if factor is None else (*factor, 255))
        out.visual = trimesh.visual.TextureVisuals(uv=mesh.corner_uv.reshape(-1, 2),
                                                   material=material)
    elif per_corner and (mesh.corner_colors is not None or mesh.face_colors is not None):
        rgb = np.full((mesh.n_faces, 3, 3), 255.0)
        if mesh.face_colors is not None:
            rgb *= mesh.face_colors[:, None, :] / 255.0
        if mesh.corner_colors is not None:
            rgb *= mesh.corner_colors / 255.0
        out.visual = trimesh.visual.ColorVisuals(
            out, vertex_colors=np.round(rgb).astype(np.uint8).reshape(-1, 3))
    elif mesh.face_colors is not None:
        out.visual = trimesh.visual.ColorVisuals(out, face_colors=mesh.face_colors)
    return out
