"""The generated scenes the documentation's examples and the schema test
use, under the file names the examples give them (tests/docs/): small
versions of the demo moon and the lab's sphere, a low mesh over three UDIM
tiles, a rifle of named parts split over two high files, a textured scan,
a job file, and the maps the diff, preview and height2normal examples read.

  prepare(folder, nmbake, nmbake_gen) -> folder
"""
import os
import re
import shutil
import subprocess

JOB = """[defaults]
size = 256
samples = 1

[[bake]]
name = "sphere"
low = "low.obj"
high = "high.ply"
outputs = ["out/sphere_normal.png"]
report = "out/sphere_report.json"

[[bake]]
name = "moon"
low = "moon_low.obj"
high = "moon_high.ply"
maps = ["normal", "height"]
outputs = ["out/moon_<MAP>.png", { path = "out/moon_<MAP>.exr", format = "exr-half" }]
"""


def run(*args, cwd):
    done = subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"fixture: {' '.join(map(str, args))} exited {done.returncode}:\n"
                           f"{done.stdout}{done.stderr}")
    return done.stdout


def udim_obj(src, dst):
    """The low sphere with its faces spread over tiles 1001, 1002 and 1011:
    each face's UVs shifted by a whole tile (a third of the faces each)."""
    lines = open(src).read().splitlines()
    vts = [l for l in lines if l.startswith("vt ")]
    n = len(vts)
    out, face = [], 0
    for line in lines:
        if line.startswith("vt "):
            continue
        if line.startswith("f "):
            shift = (0, 1, 10)[face % 3]
            face += 1
            if shift:
                def moved(m, shift=shift):
                    return f"{m.group(1)}/{int(m.group(2)) + n * (1 if shift == 1 else 2)}"
                line = re.sub(r"(\d+)/(\d+)", moved, line)
        out.append(line)
    shifted = []
    for du, dv in ((0, 0), (1, 0), (0, 1)):
        for l in vts:
            _, u, v = l.split()[:3]
            shifted.append(f"vt {float(u) + du:.7f} {float(v) + dv:.7f}")
    with open(dst, "w") as f:
        f.write("\n".join(shifted + out) + "\n")


def split_obj(src, keep):
    """The objects of an OBJ whose names are in `keep`, re-indexed, as text."""
    verts, out, current, index, seen = [], [], None, {}, []
    for line in open(src).read().splitlines():
        if line.startswith("v "):
            verts.append(line)
        elif line.startswith("o "):
            current = line[2:].strip()
            if current in keep:
                out.append(line)
        elif line.startswith("f ") and current in keep:
            ids = []
            for w in line.split()[1:]:
                v = int(w.split("/")[0])
                if v not in index:
                    index[v] = len(seen) + 1
                    seen.append(verts[v - 1])
                ids.append(str(index[v]))
            out.append("f " + " ".join(ids))
    return "\n".join(seen + out) + "\n"


def prepare(folder, nmbake, nmbake_gen, source_root):
    os.makedirs(folder, exist_ok=True)
    gen = lambda *a: run(nmbake_gen, *a, cwd=folder)  # noqa: E731
    gen("sphere", "--out-dir", ".", "--high-cells", "64", "--low-cells", "8")
    gen("moon", "--out-dir", ".", "--high-cells", "64", "--low-cells", "8", "--craters", "30")
    os.replace(os.path.join(folder, "sphere_low.obj"), os.path.join(folder, "low.obj"))
    os.replace(os.path.join(folder, "sphere_high.ply"), os.path.join(folder, "high.ply"))
    os.replace(os.path.join(folder, "sphere_cage.obj"), os.path.join(folder, "cage.obj"))
    udim_obj(os.path.join(folder, "low.obj"), os.path.join(folder, "body_low.obj"))
    shutil.copy(os.path.join(folder, "high.ply"), os.path.join(folder, "body_high.ply"))
    gen("convert", "low.obj", "low.fbx")
    # A rifle: three named parts (body, bolts, mag), the high as one file
    # and as two (body_high.obj; bolts_high.obj holding bolts and mag).
    gen("parts", "--out-dir", "parts", "--count", "3", "--high-triangles", "30000")
    names = {"p0": "body", "p1": "bolts", "p2": "mag"}
    for kind in ("low", "high"):
        text = open(os.path.join(folder, "parts", f"parts_{kind}.obj")).read()
        text = re.sub(r"^o p(\d)_", lambda m: f"o {names['p' + m.group(1)]}_", text, flags=re.M)
        with open(os.path.join(folder, f"rifle_{kind}.obj"), "w") as f:
            f.write(text)
    rifle_high = os.path.join(folder, "rifle_high.obj")
    with open(os.path.join(folder, "body_high.obj"), "w") as f:
        f.write(split_obj(rifle_high, {"body_high"}))
    with open(os.path.join(folder, "bolts_high.obj"), "w") as f:
        f.write(split_obj(rifle_high, {"bolts_high", "mag_high"}))
    shutil.rmtree(os.path.join(folder, "parts"))
    # A textured scan: game.obj (low) and scan.obj (+ scan.mtl, textures).
    run("python3", os.path.join(source_root, "tools", "gen-textured-scene"), "scan", "40", "256", cwd=folder)
    for name in os.listdir(os.path.join(folder, "scan")):
        target = {"low.obj": "game.obj", "high.obj": "scan.obj", "high.mtl": "scan.mtl"}.get(name, name)
        os.replace(os.path.join(folder, "scan", name), os.path.join(folder, target))
    os.rmdir(os.path.join(folder, "scan"))
    scan = open(os.path.join(folder, "scan.obj")).read().replace("mtllib high.mtl", "mtllib scan.mtl")
    with open(os.path.join(folder, "scan.obj"), "w") as f:
        f.write(scan)
    with open(os.path.join(folder, "job.toml"), "w") as f:
        f.write(JOB)
    # The maps other examples read.
    for d in ("out", "golden"):
        os.makedirs(os.path.join(folder, d), exist_ok=True)
    bake = lambda *a: run(nmbake, "bake", "-q", *a, cwd=folder)  # noqa: E731
    bake("--low", "moon_low.obj", "--high", "moon_high.ply", "--size", "512", "-o", "out/moon_normal.png",
         "-o", "out/moon_normal.exr")
    shutil.copy(os.path.join(folder, "out", "moon_normal.png"), os.path.join(folder, "golden", "moon_normal.png"))
    bake("--low", "low.obj", "--high", "high.ply", "--size", "512", "-o", "normal.png")
    bake("--low", "moon_low.obj", "--high", "moon_high.ply", "--size", "512", "--map", "height",
         "-o", "height.exr")
    return folder
