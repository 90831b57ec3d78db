"""Mesh export for nmbake, written from foreach_get arrays (numpy).

The low (and cage) go out as binary glTF (.glb): one vertex per loop
(position, Blender's split normal, the UV of the loop), triangles from
`loop_triangles`, so nmbake bakes over exactly the triangles Blender renders,
one node per object named after it (nmbake's parts, for name matching).
glTF's UV origin is the top-left: v is written as 1 - v (nmbake flips it
back on load).

The high goes out as binary little-endian PLY, one file per object named
after it (nmbake names a part-less file's part by its stem): positions,
normals, and 13-byte face records (a one-byte count and three uint32
indices, the loader's fast path). Smooth meshes write one vertex per
vertex with Blender's vertex normals; a mesh with flat faces or split
normals (auto smooth, custom normals) writes one vertex per loop with the
split normals, so the high's shading is what Blender shows.

Everything is in world space (modifiers applied, the evaluated depsgraph);
a mirroring transform flips the winding back so that counter-clockwise
stays the front.
"""

import json
import os
import struct

import numpy as np


def _evaluated_mesh(obj, depsgraph):
    """The object's evaluated mesh (modifiers applied); free it with
    obj_eval.to_mesh_clear()."""
    obj_eval = obj.evaluated_get(depsgraph)
    mesh = obj_eval.to_mesh()
    return obj_eval, mesh


def _array(collection, attribute, count, width, dtype):
    # The dtype must be the property's own (uint32 for loop and vertex
    # indices, float32): foreach_get then copies the raw array; another
    # dtype converts item by item, ten times slower (0.6 s against 0.06 s
    # for 2M triangles).
    out = np.empty(count * width, dtype=dtype)
    collection.foreach_get(attribute, out)
    return out.reshape(count, width) if width > 1 else out


def _transform(matrix_world, positions, normals):
    """World-space positions and normals (the inverse transpose for normals),
    float32; returns (positions, normals, mirrored)."""
    m = np.array(matrix_world, dtype=np.float64)
    linear = m[:3, :3]
    identity = np.array_equal(m, np.eye(4))
    if not identity:
        positions = (positions.astype(np.float64) @ linear.T + m[:3, 3]).astype(np.float32)
        if normals is not None:
            n = normals.astype(np.float64) @ np.linalg.inv(linear)
            length = np.linalg.norm(n, axis=1, keepdims=True)
            length[length == 0.0] = 1.0
            normals = (n / length).astype(np.float32)
    return positions, normals, bool(np.linalg.det(linear) < 0.0)


def uv_layer_of(mesh, name):
    """The UV layer named `name`, else the active render one, else None."""
    if name:
        return mesh.uv_layers.get(name)
    for layer in mesh.uv_layers:
        if layer.active_render:
            return layer
    return mesh.uv_layers.active


def low_arrays(obj, depsgraph, uv_name="", need_uvs=True):
    """Per-loop arrays of one object's evaluated mesh in world space:
    dict(positions, normals, uvs, indices (loop index per triangle corner),
    uv_name, quads (polygons of more than 3 corners)). Raises ValueError
    when the mesh has no UV map and need_uvs (zeros without one else)."""
    obj_eval, mesh = _evaluated_mesh(obj, depsgraph)
    try:
        # Before looking up the UV layer: computing split normals adds a
        # loop layer, and a layer looked up before it reads stale memory.
        mesh.calc_normals_split()
        mesh.calc_loop_triangles()
        layer = uv_layer_of(mesh, uv_name)
        if layer is None and need_uvs:
            raise ValueError("%s has no UV map%s" % (obj.name, " named %r" % uv_name if uv_name else ""))
        loop_count = len(mesh.loops)
        vertex_of_loop = _array(mesh.loops, "vertex_index", loop_count, 1, np.uint32)
        co = _array(mesh.vertices, "co", len(mesh.vertices), 3, np.float32)
        normals = _array(mesh.loops, "normal", loop_count, 3, np.float32)
        # A cage needs no UVs (its triangles are matched to the low's by order).
        uvs = _array(layer.data, "uv", loop_count, 2, np.float32) if layer is not None \
            else np.zeros((loop_count, 2), np.float32)
        indices = _array(mesh.loop_triangles, "loops", len(mesh.loop_triangles), 3, np.uint32)
        corners = _array(mesh.polygons, "loop_total", len(mesh.polygons), 1, np.int32)
        positions, normals, mirrored = _transform(obj.matrix_world, co[vertex_of_loop], normals)
        if mirrored:
            indices = indices[:, [0, 2, 1]]
        return {"positions": positions, "normals": normals, "uvs": uvs,
                "indices": np.ascontiguousarray(indices), "uv_name": layer.name if layer is not None else "",
                "quads": int((corners > 3).sum())}
    finally:
        obj_eval.to_mesh_clear()


def _pad4(data, fill=b"\0"):
    return data + fill * (-len(data) % 4)


def write_glb(path, parts):
    """Writes parts [(name, arrays of low_arrays(), plus "tangents" (N, 4)
    when given)] as one binary glTF: a node with a mesh for each part. Written to path + ".tmp", then renamed."""
    blob = bytearray()
    views, accessors, meshes, nodes = [], [], [], []

    def add(array, component_type, kind, target, bounds=False):
        array = np.ascontiguousarray(array)
        offset = len(blob)
        blob.extend(array.tobytes())
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": array.nbytes, "target": target})
        accessor = {"bufferView": len(views) - 1, "componentType": component_type,
                    "count": int(array.shape[0]) if kind != "SCALAR" else int(array.size), "type": kind}
        if bounds:
            accessor["min"] = [float(x) for x in array.min(axis=0)]
            accessor["max"] = [float(x) for x in array.max(axis=0)]
        accessors.append(accessor)
        return len(accessors) - 1

    for name, a in parts:
        uvs = a["uvs"].copy()
        uvs[:, 1] = 1.0 - uvs[:, 1]
        attributes = {
            "POSITION": add(a["positions"], 5126, "VEC3", 34962, bounds=True),
            "NORMAL": add(a["normals"], 5126, "VEC3", 34962),
            "TEXCOORD_0": add(uvs, 5126, "VEC2", 34962),
        }
        if "tangents" in a:  # Blender's own (x, y, z, bitangent sign), for --tangents file
            attributes["TANGENT"] = add(a["tangents"].astype(np.float32), 5126, "VEC4", 34962)
        indices = add(a["indices"].reshape(-1), 5125, "SCALAR", 34963)
        meshes.append({"name": name, "primitives": [{"attributes": attributes, "indices": indices, "mode": 4}]})
        nodes.append({"name": name, "mesh": len(meshes) - 1})

    document = {
        "asset": {"version": "2.0", "generator": "nmbake Blender add-on"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    text = _pad4(json.dumps(document, separators=(",", ":")).encode("utf-8"), b" ")
    binary = bytes(blob)
    total = 12 + 8 + len(text) + 8 + len(binary)
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, total))
        f.write(struct.pack("<II", len(text), 0x4E4F534A))
        f.write(text)
        f.write(struct.pack("<II", len(binary), 0x004E4942))
        f.write(binary)
    os.replace(tmp, path)


def high_arrays(obj, depsgraph):
    """One object's evaluated mesh in world space for the high side:
    dict(positions, normals, indices (vertex index per triangle corner)).

    A smooth mesh is read from the evaluated object's own mesh, read only:
    to_mesh() would copy it and compute its normals again (2M triangles:
    0.25 s against 1 s)."""
    obj_eval = obj.evaluated_get(depsgraph)
    mesh = obj_eval.data
    smooth = np.empty(len(mesh.polygons), dtype=bool)
    mesh.polygons.foreach_get("use_smooth", smooth)
    per_vertex = bool(smooth.all()) and not mesh.use_auto_smooth and not mesh.has_custom_normals
    if per_vertex:
        mesh.calc_loop_triangles()  # a cache of the mesh: computed once
        positions = _array(mesh.vertices, "co", len(mesh.vertices), 3, np.float32)
        normals = _array(mesh.vertices, "normal", len(mesh.vertices), 3, np.float32)
        indices = _array(mesh.loop_triangles, "vertices", len(mesh.loop_triangles), 3, np.uint32)
    else:
        mesh = obj_eval.to_mesh()
        try:
            mesh.calc_normals_split()
            mesh.calc_loop_triangles()
            loop_count = len(mesh.loops)
            vertex_of_loop = _array(mesh.loops, "vertex_index", loop_count, 1, np.uint32)
            co = _array(mesh.vertices, "co", len(mesh.vertices), 3, np.float32)
            positions = co[vertex_of_loop]
            normals = _array(mesh.loops, "normal", loop_count, 3, np.float32)
            indices = _array(mesh.loop_triangles, "loops", len(mesh.loop_triangles), 3, np.uint32)
        finally:
            obj_eval.to_mesh_clear()
    positions, normals, mirrored = _transform(obj.matrix_world, positions, normals)
    if mirrored:
        indices = indices[:, [0, 2, 1]]
    return {"positions": positions, "normals": normals, "indices": indices}


def write_ply(path, a):
    """Binary little-endian PLY: x y z nx ny nz, faces as 13-byte records.
    Written to path + ".tmp", then renamed."""
    vertex_count = a["positions"].shape[0]
    triangle_count = a["indices"].shape[0]
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment nmbake Blender add-on\n"
        "element vertex %d\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "element face %d\nproperty list uchar uint vertex_indices\nend_header\n" % (vertex_count, triangle_count)
    ).encode("ascii")
    vertices = np.empty((vertex_count, 6), dtype="<f4")
    vertices[:, :3] = a["positions"]
    vertices[:, 3:] = a["normals"]
    faces = np.empty(triangle_count, dtype=np.dtype([("n", "u1"), ("i", "<u4", (3,))]))
    faces["n"] = 3
    faces["i"] = a["indices"]
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header)
        f.write(vertices.tobytes())
        f.write(faces.tobytes())
    os.replace(tmp, path)


def file_name(name, extension):
    """A file name for an object's name: the name itself (nmbake matches
    parts by it), with path separators and NULs replaced."""
    safe = name.replace(os.sep, "_").replace("\0", "_")
    if os.altsep:
        safe = safe.replace(os.altsep, "_")
    if safe in ("", ".", ".."):
        safe = "_" + safe
    return safe + extension
