"""The files a model names besides itself (a glTF's buffers and images, an MTL's textures
read through trimesh): read only from inside the model's folder, only regular files, only
up to a size cap, and checked before trimesh sees them, so a hostile or broken model is a
:class:`MeshError` naming the URI and never a read of ``/etc/passwd``, ``/dev/zero`` or a
FIFO, nor a texture silently dropped.

glTF 2.0 (section 2.8, "URIs") makes a relative URI a percent-encoded path resolved
against the file's own location; ``data:`` URIs carry their bytes inline. hsr follows
that and refuses every other form (absolute paths, ``file:``, ``http:``, ``..`` out of the
folder, also when spelt ``%2e%2e`` or reached through a symbolic link).
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import os
import struct
import urllib.parse

from ..errors import MeshError
from .files import read_regular
from .images import image_size_ok

__all__ = ["FolderResolver", "check_gltf_assets", "check_gltf_nodes", "check_gltf_accessors",
           "check_gltf_primitives", "glb_chunks", "gltf_json", "MAX_NODE_DEPTH"]

# What one buffer or image file named by a model may hold.
MAX_ASSET_BYTES = 1 << 30
# Deepest node tree read: trimesh multiplies the matrices down each path with
# numpy.linalg.multi_dot, whose chain ordering costs O(depth^3) per node (a 256-deep chain
# took 51 s, 64 deep 0.2 s); skeletons and CAD assemblies stay far below this.
MAX_NODE_DEPTH = 64
# Largest magnitude of a node's matrix or TRS value (as hsr.scene.mesh.MAX_COORDINATE
# bounds positions): beyond it products overflow to inf.
MAX_NODE_VALUE = 1e15


def _resolver_base():
    import trimesh.resolvers

    return trimesh.resolvers.Resolver


class FolderResolver:
    """Reads the files a model names, relative to ``folder``, for trimesh (which calls
    :meth:`get`). Every read is checked (see the module notes) and kept, so a file the
    checks read is not read again by trimesh. Build it with :func:`folder_resolver`."""

    def __init__(self, folder: str, label: str, max_bytes: int = MAX_ASSET_BYTES):
        self.folder = os.path.realpath(folder)
        self.label = label
        self.max_bytes = max_bytes
        self._read: dict[str, bytes] = {}
        self.paths: list[str] = []  # the files read, in order: inputs no output replaces

    def path_of(self, uri) -> str:
        """The real path inside the folder that the relative ``uri`` names, or a
        :class:`MeshError` saying why it is refused."""
        if not isinstance(uri, str) or not uri.strip():
            raise MeshError(f"{self.label}: a file reference must be a non-empty string, "
                            f"got {uri!r}")
        name = urllib.parse.unquote(uri.strip())
        scheme = urllib.parse.urlsplit(name).scheme
        if (len(scheme) > 1 or os.path.isabs(name) or name.startswith(("\\", "~"))
                or "\x00" in name):
            raise MeshError(f"{self.label}: refuses {uri!r}: hsr reads only files in the "
                            f"model's folder, named by a relative path")
        path = os.path.realpath(os.path.join(self.folder, name))
        if os.path.commonpath([path, self.folder]) != self.folder:
            raise MeshError(f"{self.label}: refuses {uri!r}: it points outside the model's "
                            f"folder {self.folder}")
        return path

    def get(self, uri) -> bytes:
        if not isinstance(uri, str):
            raise MeshError(f"{self.label}: a file reference must be a non-empty string, "
                            f"got {uri!r}")
        if uri in self._read:
            return self._read[uri]
        if uri.startswith("data:"):
            data = data_uri_bytes(uri, self.label)
        else:
            path = self.path_of(uri)
            try:
                data = read_regular(path, "file", self.max_bytes)
            except MeshError as exc:
                raise MeshError(f"{self.label}: names {uri!r}: {exc}") from None
            self.paths.append(path)
        self._read[uri] = data
        return data

    def __getitem__(self, uri):
        return self.get(uri)

    def __contains__(self, uri) -> bool:
        try:
            self.get(uri)
        except MeshError:
            return False
        return True

    def keys(self):
        return iter(())

    def write(self, name, data):
        raise MeshError(f"{self.label}: hsr does not write beside a model it reads")

    def namespaced(self, namespace):
        return folder_resolver(self.path_of(namespace), self.label, self.max_bytes)


def folder_resolver(folder: str, label: str, max_bytes: int = MAX_ASSET_BYTES):
    """A :class:`FolderResolver` that is also a ``trimesh.resolvers.Resolver`` (trimesh
    checks the type), made here so trimesh is imported only when a file needs it."""
    cls = type("TrimeshFolderResolver", (FolderResolver, _resolver_base()), {})
    return cls(folder, label, max_bytes)


def data_uri_bytes(uri: str, label: str) -> bytes:
    """The bytes of a base64 ``data:`` URI (RFC 2397), or a :class:`MeshError`."""
    head, sep, payload = uri.partition(",")
    if not sep or not head.endswith(";base64"):
        raise MeshError(f"{label}: a data: URI must be base64 ('data:...;base64,...'), "
                        f"got {uri[:40]!r}")
    try:
        return base64.b64decode(payload, validate=True)
    except (binascii.Error, ValueError) as exc:
        raise MeshError(f"{label}: a data: URI holds bad base64 ({exc})") from None


def glb_chunks(read, size: int, label: str) -> tuple:
    """``((JSON offset, length), (BIN offset, length) or None)`` of a GLB of ``size``
    bytes whose bytes ``read(offset, count)`` gives (glTF 2.0, section 4.4: a 12-byte
    header, then chunks of an 8-byte header and their data; the first is JSON), checked
    against the lengths the file states. One function for hsr.load (bytes in memory)
    and the streamed reader (a file), so both refuse a broken file alike."""
    if size < 20:
        raise MeshError(f"{label}: a GLB needs a 12-byte header and a chunk, got "
                        f"{size} bytes")
    magic, version, total = struct.unpack("<4sII", read(0, 12))
    if magic != b"glTF":
        raise MeshError(f"{label}: not a binary glTF file")
    if version != 2:
        raise MeshError(f"{label}: GLB version {version}; hsr reads glTF 2.0")
    if total != size:
        raise MeshError(f"{label}: the GLB header says {total:,} bytes, the file has "
                        f"{size:,}")
    offset, json_span, bin_span = 12, None, None
    while offset < size:
        if offset + 8 > size:
            raise MeshError(f"{label}: a GLB chunk header is cut off at byte {offset}")
        length, kind = struct.unpack("<I4s", read(offset, 8))
        if offset + 8 + length > size:
            raise MeshError(f"{label}: a GLB chunk at byte {offset} claims {length:,} bytes "
                            f"past the end of the file")
        if json_span is None:
            if kind != b"JSON":
                raise MeshError(f"{label}: not a glTF file (the first GLB chunk is not "
                                f"JSON)")
            json_span = (offset + 8, length)
        elif kind == b"BIN\x00" and bin_span is None:
            bin_span = (offset + 8, length)
        offset += 8 + length
    return json_span, bin_span


def gltf_json(text: bytes, label: str) -> dict:
    """The glTF JSON object in ``text`` (a .gltf file, or a GLB's JSON chunk)."""
    try:
        header = json.loads(text)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise MeshError(f"{label}: not a glTF file ({exc})"[:300]) from None
    if not isinstance(header, dict):
        raise MeshError(f"{label}: not a glTF file (the JSON is not an object)")
    return header


def _index(value, count: int, what: str, label: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < count:
        raise MeshError(f"{label}: {what} must be an index below {count}, got {value!r}")
    return value


def _natural(entry: dict, key: str, default, what: str, label: str) -> int:
    value = entry.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise MeshError(f"{label}: {what}.{key} must be a whole number >= 0, got {value!r}")
    return value


def _list(header: dict, key: str, label: str) -> list:
    value = header.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise MeshError(f"{label}: '{key}' must be a list of objects")
    return value


def check_gltf_assets(header: dict, chunk, resolver: FolderResolver, label: str,
                      max_pixels: int) -> None:
    """Check what a glTF's ``header`` names before anything reads its data: every
    buffer's bytes (``chunk``, the GLB's binary chunk: bytes or anything that slices
    like them, or None; a data: URI; a file in the folder, through ``resolver``, which
    keeps them for trimesh) at least as long as it says, every buffer view inside its
    buffer, every accessor inside its view (strides, offsets, counts), every primitive's
    accessors of the kinds it needs with a triangle count that is whole, and every image
    a readable picture of at most ``max_pixels``. Raises :class:`MeshError` naming the
    buffer, view, accessor, mesh or image. hsr.load and the streamed reader both call
    it."""
    buffers = _list(header, "buffers", label)
    views = _list(header, "bufferViews", label)
    images = _list(header, "images", label)
    stored = []
    for k, buffer in enumerate(buffers):
        what = f"buffer {k}"
        length = _natural(buffer, "byteLength", None, what, label)
        if "uri" in buffer:
            blob = resolver.get(buffer["uri"])
        elif k == 0 and chunk is not None:
            blob = chunk
        else:
            raise MeshError(f"{label}: {what} has no uri and no GLB binary chunk holds it")
        if len(blob) < length:
            raise MeshError(f"{label}: {what} says {length:,} bytes, holds {len(blob):,}")
        stored.append(blob)
    spans = []
    for k, view in enumerate(views):
        what = f"bufferView {k}"
        b = _index(view.get("buffer"), len(buffers), f"{what}.buffer", label)
        start = _natural(view, "byteOffset", 0, what, label)
        length = _natural(view, "byteLength", None, what, label)
        if start + length > len(stored[b]):
            raise MeshError(f"{label}: {what} (bytes {start:,}..{start + length:,}) runs past "
                            f"the end of buffer {b} ({len(stored[b]):,} bytes)")
        if "byteStride" in view:
            stride = view["byteStride"]
            if isinstance(stride, bool) or not isinstance(stride, int) \
                    or not 4 <= stride <= 252 or stride % 4:
                raise MeshError(f"{label}: {what}.byteStride must be a multiple of 4 in "
                                f"4..252, got {stride!r}"[:200])
        spans.append((b, start, length))
    check_gltf_accessors(header, views, label)
    check_gltf_primitives(header, label)
    for k, image in enumerate(images):
        what = f"image {k}"
        if "bufferView" in image:
            b, start, length = spans[_index(image["bufferView"], len(views),
                                            f"{what}.bufferView", label)]
            blob = stored[b][start:start + length]
        elif "uri" in image:
            blob = resolver.get(image["uri"])
        else:
            raise MeshError(f"{label}: {what} has neither a uri nor a bufferView")
        problem = image_size_ok(blob, max_pixels)
        if problem:
            raise MeshError(f"{label}: {what}: {problem}")


# glTF 2.0, section 3.6.2: component types (bytes each) and element types (components).
COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9,
                   "MAT4": 16}
INDEX_COMPONENTS = (5121, 5123, 5125)


def check_gltf_accessors(header: dict, views: list, label: str) -> None:
    """Every accessor a known component and element type, a whole count, and (when it
    has a buffer view) a whole offset, with its elements (at the view's stride) inside
    the view."""
    for k, acc in enumerate(_list(header, "accessors", label)):
        what = f"accessor {k}"
        kind, element = acc.get("componentType"), acc.get("type")
        if isinstance(kind, bool) or not isinstance(kind, int) or kind not in COMPONENT_BYTES \
                or not isinstance(element, str) or element not in TYPE_COMPONENTS:
            raise MeshError(f"{label}: {what} has an unknown componentType or type "
                            f"({acc.get('componentType')!r}, {acc.get('type')!r})"[:200])
        count = _natural(acc, "count", None, what, label)
        if count < 1:  # glTF 2.0, section 5.1: count minimum 1
            raise MeshError(f"{label}: {what}.count must be at least 1, got 0")
        offset = _natural(acc, "byteOffset", 0, what, label)
        if "bufferView" not in acc:
            continue
        view = views[_index(acc["bufferView"], len(views), f"{what}.bufferView", label)]
        size = COMPONENT_BYTES[acc["componentType"]] * TYPE_COMPONENTS[acc["type"]]
        stride = view.get("byteStride", size)
        if stride < size:
            raise MeshError(f"{label}: {what}: its view's byteStride {stride} is less than "
                            f"an element ({size} bytes)")
        end = offset + stride * (count - 1) + size if count else offset
        if end > view["byteLength"]:
            raise MeshError(f"{label}: {what} (bytes {offset:,}..{end:,} of bufferView "
                            f"{acc['bufferView']}) reaches past its view "
                            f"({view['byteLength']:,} bytes)")


def check_gltf_primitives(header: dict, label: str) -> None:
    """Every primitive's attributes and indices name accessors; positions are float VEC3,
    indices unsigned integer scalars; triangles (mode 4, the default) come in whole
    threes of indices (or of positions without indices)."""
    accessors = _list(header, "accessors", label)
    for m, mesh in enumerate(_list(header, "meshes", label)):
        primitives = mesh.get("primitives", [])
        if not isinstance(primitives, list) or not all(isinstance(p, dict)
                                                       for p in primitives):
            raise MeshError(f"{label}: mesh {m}: primitives must be a list of objects")
        for p, prim in enumerate(primitives):
            what = f"mesh {m} primitive {p}"
            attributes = prim.get("attributes", {})
            if not isinstance(attributes, dict):
                raise MeshError(f"{label}: {what}: attributes must be an object")
            for name, index in attributes.items():
                _index(index, len(accessors), f"{what}'s {name}", label)
            mode = prim.get("mode", 4)
            if isinstance(mode, bool) or not isinstance(mode, int) or not 0 <= mode <= 6:
                raise MeshError(f"{label}: {what}: mode must be 0..6, got {mode!r}"[:200])
            position = attributes.get("POSITION")
            if position is not None and (accessors[position].get("type") != "VEC3"
                                         or accessors[position].get("componentType") != 5126):
                raise MeshError(f"{label}: {what}: POSITION must be a float VEC3 accessor")
            counted = position
            if "indices" in prim:
                counted = _index(prim["indices"], len(accessors), f"{what}'s indices",
                                 label)
                acc = accessors[counted]
                if acc.get("type") != "SCALAR" or acc.get("componentType") \
                        not in INDEX_COMPONENTS:
                    raise MeshError(f"{label}: {what}: indices must be unsigned integer "
                                    f"scalars")
            if mode == 4 and counted is not None and accessors[counted]["count"] % 3:
                raise MeshError(f"{label}: {what}: {accessors[counted]['count']:,} "
                                f"{'indices' if 'indices' in prim else 'vertices'} do not "
                                f"make whole triangles (not a multiple of 3)")


def check_gltf_nodes(header: dict, label: str) -> None:
    """Refuse a node graph that is not a forest of strict trees (glTF 2.0, section 3.5.3:
    no node has two parents, none is its own ancestor), that is deeper than
    :data:`MAX_NODE_DEPTH`, or whose children, matrix or TRS values are malformed
    (a child or mesh index out of range, a count other than 16 / 3 / 4, a value that is not a finite
    number). Raises :class:`MeshError` naming the node."""
    nodes = _list(header, "nodes", label)
    meshes = _list(header, "meshes", label)
    parent = {}
    for k, node in enumerate(nodes):
        if "mesh" in node:
            _index(node["mesh"], len(meshes), f"node {k}'s mesh", label)
        children = node.get("children", [])
        if not isinstance(children, list):
            raise MeshError(f"{label}: node {k}: children must be a list of node indices")
        for child in children:
            _index(child, len(nodes), f"node {k}'s child", label)
            if child in parent or child == k:
                raise MeshError(f"{label}: node {child} has two parents or is its own "
                                f"child (nodes must form trees)")
            parent[child] = k
        for key, count in (("matrix", 16), ("translation", 3), ("rotation", 4),
                           ("scale", 3)):
            if key in node:
                value = node[key]
                if (not isinstance(value, list) or len(value) != count
                        or not all(_finite_number(v) for v in value)):
                    raise MeshError(f"{label}: node {k}: {key} must be {count} finite "
                                    f"numbers, got {value!r}"[:200])
    for k in range(len(nodes)):  # walk up from each node: a cycle never reaches a root
        depth, node = 0, k
        while node in parent:
            node, depth = parent[node], depth + 1
            if node == k:
                raise MeshError(f"{label}: node {k} is its own ancestor (a cycle)")
            if depth > MAX_NODE_DEPTH:
                raise MeshError(f"{label}: node {k} lies more than {MAX_NODE_DEPTH} levels "
                                f"deep; hsr reads node trees up to {MAX_NODE_DEPTH} deep")


def _finite_number(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value) and abs(value) <= MAX_NODE_VALUE)
