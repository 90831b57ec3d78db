#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz harnesses (tests/fuzz/corpus/<harness>/):
small files of every form each parser accepts, so the fuzzer starts from
valid input. Images, tile files, cache entries, .glb and .fbx come from nmbake and
nmbake-gen (pass the build folder):
    python3 tests/fuzz/make_corpus.py build
tools/fuzz adds the small models of Debian's assimp-testmodels at run time.
"""
import base64
import json
import os
import struct
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))


def put(harness, name, data):
    folder = os.path.join(HERE, "corpus", harness)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


QUAD = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]


def obj_seeds():
    put("obj", "quad_vt_vn.obj", "".join(f"v {x} {y} {z}\n" for x, y, z in QUAD) +
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n")
    put("obj", "polygon_negative.obj", "o part\ng grp\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in QUAD) +
        "s 1\nusemtl m\nf -4 -3 -2 -1\n")
    put("obj", "normals_only.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\r\n# comment\n")
    put("obj", "exponents.obj", "v 1e-3 +2.5E+1 -0\nv 1e-50 3 4\nv 5 6 7\nvt .5 .5\nf 1/1 2/1 3/1\n")


def ply_header(fmt, vertex_props, face_list="uchar int"):
    h = f"ply\nformat {fmt} 1.0\ncomment seed\nelement vertex 4\n"
    h += "".join(f"property {t} {n}\n" for t, n in vertex_props)
    h += f"element face 2\nproperty list {face_list} vertex_indices\nend_header\n"
    return h


def ply_seeds():
    props = [("float", "x"), ("float", "y"), ("float", "z"), ("float", "nx"), ("float", "ny"), ("float", "nz"),
             ("float", "u"), ("float", "v")]
    rows = [(x, y, z, 0, 0, 1, (x + 1) / 2, (y + 1) / 2) for x, y, z in QUAD]
    text = ply_header("ascii", props) + "".join(" ".join(str(c) for c in r) + "\n" for r in rows)
    put("ply", "ascii.ply", text + "3 0 1 2\n3 0 2 3\n")
    for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        body = b"".join(struct.pack(e + "8f", *r) for r in rows)
        body += struct.pack(e + "B3i", 3, 0, 1, 2) + struct.pack(e + "B3i", 3, 0, 2, 3)
        put("ply", fmt + ".ply", ply_header(fmt, props).encode() + body)
    # A quad face and other types: the generic (one-thread) binary path.
    props2 = [("double", "x"), ("double", "y"), ("double", "z"), ("uchar", "red"), ("short", "s"), ("ushort", "t")]
    body = b"".join(struct.pack("<3dBhH", x, y, z, 9, 1, 2) for x, y, z in QUAD)
    body += struct.pack("<H4H", 4, 0, 1, 2, 3) + struct.pack("<H3H", 3, 0, 2, 3)
    put("ply", "generic.ply", ply_header("binary_little_endian", props2, "ushort ushort").encode() + body)


def job_seeds():
    put("job", "full.toml", """[defaults]
size = 64
samples = 4
space = "tangent"
green = "down"
front = "2%"
back = 0.25
hit = "nearest"
cage_mode = "interpolated"
high_normals = "face"
padding = 4
build_quality = "medium"
bvh = "compact"
ignore_backfaces = true
max_memory = "1G"

[[bake]]
name = "a"
low = "low.obj"
high = "high.ply"
cage = "cage.obj"
outputs = ["a.png", { path = "a.exr", format = "exr-half" }]
report = "a.json"
debug_dump = "dbg"

[[bake]]
width = 32
height = 16
low = "low.ply"
high = "high.obj"
outputs = ["b.tif"]
front = "auto"
""")
    put("job", "minimal.toml", '[[bake]]\nlow = "l.obj"\nhigh = "h.obj"\noutputs = ["o.png"]\n')


def image_seeds(nmbake):
    with tempfile.TemporaryDirectory() as d:
        low, high = quad_meshes(d)
        outputs = [("png8", "a.png", 0), ("png16", "b.png", 0), ("exr-half", "c.exr", 1), ("exr-float", "d.exr", 1),
                   ("tiff16", "e.tif", 2)]
        for fmt, name, tag in outputs:
            out = os.path.join(d, name)
            subprocess.run([nmbake, "bake", "-q", "--low", low, "--high", high, "-o", out, "--size", "8",
                            "--samples", "1", "--format", fmt], check=True)
            with open(out, "rb") as f:
                put("image", fmt + "_" + name, bytes([tag]) + f.read())


def quad_meshes(d):
    low, high = os.path.join(d, "low.obj"), os.path.join(d, "high.obj")
    with open(low, "w") as f:
        f.write("".join(f"v {x} {y} {z}\n" for x, y, z in QUAD) +
                "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    with open(high, "w") as f:
        f.write("v -2 -2 0.1\nv 2 -2 0.2\nv 2 2 0.1\nv -2 2 0.0\nf 1 2 3\nf 1 3 4\n")
    return low, high


def tile_seeds(nmbake):
    # Tile files of the quad without their 8-byte trailer (fuzz_tile.cpp
    # appends the checksum): a map set and the normal map alone as whole
    # bakes (1/1, which the harness merges), and a tile of two.
    with tempfile.TemporaryDirectory() as d:
        low, high = quad_meshes(d)
        cases = [("map_set_1of1", "normal,height,ao,curvature,position,miss,thickness,id", "1/1"),
                 ("normal_1of1", "normal", "1/1"), ("height_ao_2of2", "height,ao", "2/2")]
        for name, maps, tile in cases:
            out = os.path.join(d, name + ".nmt")
            subprocess.run([nmbake, "bake", "-q", "--low", low, "--high", high, "-o", "m_<MAP>.png", "--size", "8",
                            "--samples", "1", "--padding", "2", "--map", maps, "--ao-rays", "2", "--thickness-rays",
                            "2", "--tile", tile, "--tile-file", out], check=True, cwd=d)
            with open(out, "rb") as f:
                put("tile", name, f.read()[:-8])


def cache_seeds(nmbake):
    # Cache entries in fuzz_cache.cpp's form (records split by a line
    # "=====": the manifest, the report, then "name\nbytes" per file; bytes
    # "->T" make a symlink to T): the entry nmbake stores for the quad with
    # the harness's outputs (a.png, b_<UDIM>.exr), its key replaced by the
    # harness's; and that entry with a symlinked map, a manifest naming a
    # file outside the entry, and a manifest of an older nmbake.
    sep = b"\n=====\n"
    key = "0123456789abcdeffedcba9876543210"
    with tempfile.TemporaryDirectory() as d:
        low, high = quad_meshes(d)
        subprocess.run([nmbake, "bake", "-q", "--low", low, "--high", high, "-o", "a.png", "-o", "b_<UDIM>.exr",
                        "--size", "16", "--samples", "1", "--cache", "c"], check=True, cwd=d)
        (entry,) = os.listdir(os.path.join(d, "c"))
        folder = os.path.join(d, "c", entry)

        def read(name):
            with open(os.path.join(folder, name), "rb") as f:
                return f.read()
        manifest = json.loads(read("manifest.json"))
        manifest["key"] = key
        names = [f["file"] for f in manifest["files"]]

        def entry_bytes(m, files):
            return sep.join([json.dumps(m, indent=2).encode(), read("report.json")] +
                            [name.encode() + b"\n" + data for name, data in files])
        files = [(n, read(n)) for n in names]
        put("cache", "whole", entry_bytes(manifest, files))
        put("cache", "symlinked_map", entry_bytes(manifest, [(names[0], b"->../../secret")] + files[1:]))
        outside = json.loads(json.dumps(manifest))
        outside["files"][0]["file"] = "../../secret"
        put("cache", "name_outside", entry_bytes(outside, files))
        older = json.loads(json.dumps(manifest))
        del older["report"]
        for f in older["files"]:
            del f["size"], f["xxh3"]
        put("cache", "older_manifest", entry_bytes(older, files))


def bake_seeds():
    # flags, counts, then coordinates (+ UVs) and indices of the low mesh,
    # then of the high mesh (see fuzz_bake.cpp).
    counts = bytes([1, 1, 1, 1])  # 4 vertices and 2 triangles each
    low_uv = b"".join(bytes([x, y, 126, u, v]) for x, y, u, v in
                      ((94, 94, 0, 0), (158, 94, 255, 0), (158, 158, 255, 255), (94, 158, 0, 255)))
    low_plain = b"".join(bytes([x, y, 126]) for x, y in ((94, 94), (158, 94), (158, 158), (94, 158)))
    indices = bytes([0, 1, 2, 0, 2, 3])
    high = b"".join(bytes([x, y, z]) for x, y, z in ((60, 60, 130), (200, 60, 131), (200, 200, 130), (60, 200, 129)))
    put("bake", "quad_uv", bytes([1]) + counts + low_uv + indices + high + indices)
    put("bake", "no_uv", bytes([0]) + counts + low_plain + indices + high + indices)
    put("bake", "nearest_object", bytes([1 | 2 | 4 | 16]) + counts + low_uv + indices + high + indices)
    put("bake", "distances", bytes([1 | 32]) + counts + low_uv + indices + high + indices + bytes([5, 140]))
    put("bake", "far_vertex", bytes([1]) + counts + bytes([255]) + low_uv[1:] + indices + high + indices)


def gltf_json_seed():
    # Two triangles with positions, normals and UVs in one data: buffer.
    import struct as st
    pos = b"".join(st.pack("<3f", x, y, z) for x, y, z in QUAD)
    nrm = st.pack("<3f", 0, 0, 1) * 4
    uv = b"".join(st.pack("<2f", (x + 1) / 2, (y + 1) / 2) for x, y, _ in QUAD)
    idx = st.pack("<6H", 0, 1, 2, 0, 2, 3)
    blob = pos + nrm + uv + idx
    views = [(0, 48), (48, 48), (96, 32), (128, 12)]
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "quad_low", "mesh": 0, "translation": [0, 0, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}]}],
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    }
    put("gltf", "quad_data_uri.gltf", bytes([0]) + json.dumps(doc).encode())


def tiny_png():
    # A 2x2 RGB PNG (an embedded texture's bytes).
    import zlib
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)
    rows = b"\0\xff\0\0\0\xff\0" + b"\0\0\0\xff\xff\xff\xff"
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def material_seeds():
    # glTF: the quad with a material whose base colour texture is a data: URI
    # PNG (flag 8: materials, corner UVs, embedded images decoded).
    with open(os.path.join(HERE, "corpus", "gltf", "quad_data_uri.gltf"), "rb") as f:
        doc = json.loads(f.read()[1:])
    doc["meshes"][0]["primitives"][0]["material"] = 0
    doc["materials"] = [{"name": "albedo", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    doc["textures"] = [{"source": 0}]
    doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(tiny_png()).decode()}]
    put("gltf", "quad_material.gltf", bytes([8]) + json.dumps(doc).encode())
    # Collada: the quad with an emission colour and a diffuse texture file (a <hex>
    # embedded image makes Assimp 5.2.5 abort on an assertion).
    pos = " ".join("%g %g %g" % p for p in QUAD)
    dae = ('<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">'
           '<asset><up_axis>Y_UP</up_axis></asset>'
           '<library_images><image id="img"><init_from>albedo.png</init_from></image></library_images>'
           '<library_effects><effect id="fx"><profile_COMMON>'
           '<newparam sid="s"><surface type="2D"><init_from>img</init_from></surface></newparam>'
           '<newparam sid="t"><sampler2D><source>s</source></sampler2D></newparam>'
           '<technique sid="c"><lambert><emission><color>0.1 0.2 0.3 1</color></emission>'
           '<diffuse><texture texture="t" texcoord="UV"/></diffuse></lambert></technique>'
           '</profile_COMMON></effect></library_effects>'
           '<library_materials><material id="m" name="paint"><instance_effect url="#fx"/></material></library_materials>'
           '<library_geometries><geometry id="g"><mesh>'
           '<source id="p"><float_array id="pa" count="12">' + pos + '</float_array><technique_common>'
           '<accessor source="#pa" count="4" stride="3"><param name="X" type="float"/><param name="Y" type="float"/>'
           '<param name="Z" type="float"/></accessor></technique_common></source>'
           '<source id="u"><float_array id="ua" count="8">0 0 1 0 1 1 0 1</float_array><technique_common>'
           '<accessor source="#ua" count="4" stride="2"><param name="S" type="float"/><param name="T" type="float"/>'
           '</accessor></technique_common></source>'
           '<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>'
           '<triangles material="sym" count="2"><input semantic="VERTEX" source="#v" offset="0"/>'
           '<input semantic="TEXCOORD" source="#u" offset="0" set="0"/><p>0 1 2 0 2 3</p></triangles>'
           '</mesh></geometry></library_geometries>'
           '<library_visual_scenes><visual_scene id="vs"><node id="quad" name="quad"><instance_geometry url="#g">'
           '<bind_material><technique_common><instance_material symbol="sym" target="#m"/></technique_common>'
           '</bind_material></instance_geometry></node></visual_scene></library_visual_scenes>'
           '<scene><instance_visual_scene url="#vs"/></scene></COLLADA>')
    put("assimp", "quad_material.dae", bytes([1 | 8]) + dae.encode())


def assimp_text_seeds():
    stl = "solid quad\n"
    for tri in ((0, 1, 2), (0, 2, 3)):
        stl += " facet normal 0 0 1\n  outer loop\n"
        stl += "".join("   vertex %g %g %g\n" % QUAD[i] for i in tri)
        stl += "  endloop\n endfacet\n"
    put("assimp", "quad_ascii.stl", bytes([3]) + (stl + "endsolid quad\n").encode())
    import struct as st
    binary = b"\0" * 80 + st.pack("<I", 2)
    for tri in ((0, 1, 2), (0, 2, 3)):
        binary += st.pack("<3f", 0, 0, 1) + b"".join(st.pack("<3f", *QUAD[i]) for i in tri) + b"\0\0"
    put("assimp", "quad_binary.stl", bytes([3]) + binary)


def mesh_format_seeds(build):
    gen = os.path.join(build, "nmbake-gen")
    with tempfile.TemporaryDirectory() as d:
        obj = os.path.join(d, "parts.obj")
        with open(obj, "w") as f:
            f.write("o a_low\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in QUAD) +
                    "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
                    "o b_low\nv 0 0 1\nv 1 0 1\nv 0 1 1\nvt 0 0\nvt 1 0\nvt 0 1\nf 5/5/1 6/6/1 7/7/1\n")
        for name, harness, tag in (("parts.glb", "gltf", 1), ("parts.fbx", "assimp", 0)):
            out = os.path.join(d, name)
            subprocess.run([gen, "convert", obj, out], check=True)
            with open(out, "rb") as f:
                put(harness, name, bytes([tag]) + f.read())


if __name__ == "__main__":
    obj_seeds()
    ply_seeds()
    job_seeds()
    bake_seeds()
    gltf_json_seed()
    assimp_text_seeds()
    material_seeds()
    if len(sys.argv) > 1:
        build = sys.argv[1]
        if os.path.isfile(build):  # the old form: the nmbake binary
            build = os.path.dirname(build)
        image_seeds(os.path.join(build, "nmbake"))
        tile_seeds(os.path.join(build, "nmbake"))
        cache_seeds(os.path.join(build, "nmbake"))
        mesh_format_seeds(build)
