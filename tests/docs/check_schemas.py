#!/usr/bin/env python3
"""The JSON Schemas of the documentation against what nmbake writes and
reads (ctest Docs.Schemas):

  tests/docs/check_schemas.py NMBAKE NMBAKE_GEN SOURCE_ROOT

* bake reports of several option mixes (every map of the map set, UDIM
  tiles, parts and several high files, an id map, adaptive sampling, a cage
  file, a tile of a farm bake, the high's textures and normal textures, an
  unwrapped low, a job through the cache, baked and then cached) validate
  against docs/schemas/report.schema.json, which is closed: a field the
  report gains and the schema lacks fails here;
* every job file under scenes/, the test scenes' job file and every TOML
  block of the documentation holding a [[bake]] validate against
  docs/schemas/job.schema.json, and that schema holds every key of
  `nmbake bake --print-options` and is what tools/job-schema writes today;
* the reference tables are what tools/docs-tables writes from the schemas.

Needs Debian's python3-jsonschema (tools/setup): without it, exit 77 (ctest
SKIP) with a message.
"""
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import tomllib

try:
    import jsonschema
except ImportError:
    print("SKIP: python3-jsonschema is not installed (tools/setup installs it)")
    sys.exit(77)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fixture  # noqa: E402

failures = []


def check(ok, message):
    if not ok:
        failures.append(message)


def validator(path):
    schema = json.loads(path.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def errors_of(v, instance):
    return [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message[:300]}" for e in v.iter_errors(instance)]


def main():
    nmbake, gen, root = (pathlib.Path(a).resolve() for a in sys.argv[1:4])
    report_v = validator(root / "docs/schemas/report.schema.json")
    job_v = validator(root / "docs/schemas/job.schema.json")

    with tempfile.TemporaryDirectory(prefix="nmbake-schemas-") as tmp:
        d = fixture.prepare(os.path.join(tmp, "scenes"), nmbake, gen, root)
        subprocess.run([sys.executable, str(root / "tools/gen-textured-scene"), "textured", "20", "128", "--normal"],
                       cwd=d, check=True, capture_output=True)
        # A low without UVs: the bake unwraps it.
        text = open(os.path.join(d, "low.obj")).read()
        text = "\n".join(l for l in text.splitlines() if not l.startswith("vt "))
        text = re.sub(r"(\d+)/\d*/(\d+)", r"\1//\2", text)
        with open(os.path.join(d, "low_nouv.obj"), "w") as f:
            f.write(text + "\n")
        small = ["--size", "128", "-q"]
        mixes = {
            "plain, cage file": ["--low", "low.obj", "--high", "high.ply", "--cage", "cage.obj", "-o", "a.png"],
            "every map": ["--low", "moon_low.obj", "--high", "moon_high.ply", "--map",
                          "normal,height,ao,bent-normal,curvature,thickness,position,object-normal,miss,id",
                          "--ao-rays", "4", "--thickness-rays", "4", "-o", "b_<MAP>.png"],
            "UDIM": ["--low", "body_low.obj", "--high", "body_high.ply", "--map", "normal,ao", "--ao-rays", "4",
                     "-o", "c_<MAP>.<UDIM>.png", "-o", "c_<MAP>.<UDIM>.exr"],
            "parts, several high files, id map": ["--low", "rifle_low.obj", "--high", "body_high.obj", "--high",
                                                  "bolts_high.obj", "--map", "normal,id", "-o", "d_<MAP>.png"],
            "adaptive": ["--low", "moon_low.obj", "--high", "moon_high.ply", "--samples", "adaptive",
                         "--adaptive-max", "64", "-o", "e.png"],
            "tile of a farm bake": ["--low", "low.obj", "--high", "high.ply", "-o", "f.png", "--tile", "1/2"],
            "textures": ["--low", "game.obj", "--high", "scan.obj", "--map",
                         "normal,base-color,roughness,metallic,emissive,opacity", "-o", "g_<MAP>.png"],
            "high normal textures, preset": ["--low", "textured/low.obj", "--high", "textured/high.obj",
                                             "--preset", "unity", "-o", "h.tga"],
            "unwrapped low": ["--low", "low_nouv.obj", "--high", "high.ply", "-o", "i.png"],
        }
        reports = []
        for name, args in mixes.items():
            report = os.path.join(d, re.sub(r"\W+", "_", name) + ".json")
            done = subprocess.run([str(nmbake), "bake", *args, *small, "--report", report], cwd=d,
                                  capture_output=True, text=True)
            check(done.returncode == 0, f"bake '{name}' exited {done.returncode}: {done.stderr.strip()}")
            if done.returncode == 0:
                reports.append((name, report))
        # A job through the cache: baked (with a key), then served from it.
        for run in ("job, baked into the cache", "job, served from the cache"):
            done = subprocess.run([str(nmbake), "bake", "job.toml", "--cache", "cache", "-q"], cwd=d,
                                  capture_output=True, text=True)
            check(done.returncode == 0, f"{run}: exit {done.returncode}: {done.stderr.strip()}")
            snapshot = os.path.join(d, re.sub(r"\W+", "_", run) + ".json")
            os.replace(os.path.join(d, "out/sphere_report.json"), snapshot)
            reports.append((run, snapshot))
        for name, path in reports:
            r = json.loads(open(path).read())
            errors = errors_of(report_v, r)
            check(not errors, f"report of '{name}' does not validate:\n  " + "\n  ".join(errors))
        cached = json.loads(open(os.path.join(d, "job_served_from_the_cache.json")).read())
        check(cached.get("cached") is True and "key" in cached, "the second job run was not served from the cache")
        print(f"report.schema.json: {len(reports)} reports validated ({', '.join(n for n, _ in reports)})")

        # Job files: scenes/, the test scenes' job file, the docs' TOML blocks.
        jobs = [(str(p.relative_to(root)), p.read_text()) for p in sorted((root / "scenes").rglob("*.toml"))]
        jobs.append(("tests/docs/fixture.py JOB", fixture.JOB))
        for page in sorted((root / "docs").rglob("*.md")):
            for m in re.finditer(r"^( *)```toml\n(.*?)^\1```", page.read_text(), re.S | re.M):
                block = "\n".join(l[len(m.group(1)):] for l in m.group(2).splitlines())
                if re.search(r"^\[\[bake\]\]", block, re.M):
                    line = page.read_text()[: m.start()].count("\n") + 1
                    jobs.append((f"{page.relative_to(root)}:{line}", block))
        for name, text in jobs:
            try:
                data = tomllib.loads(text)
            except tomllib.TOMLDecodeError as e:
                check(False, f"{name}: not TOML: {e}")
                continue
            errors = errors_of(job_v, data)
            check(not errors, f"job file {name} does not validate:\n  " + "\n  ".join(errors))
        print(f"job.schema.json: {len(jobs)} job files validated ({', '.join(n for n, _ in jobs)})")

        # Every key of the option table is in the schema.
        out = subprocess.run([str(nmbake), "bake", "--low", "l.obj", "--high", "h.ply", "-o", "n.png",
                              "--print-options"], capture_output=True, text=True, check=True).stdout
        keys = set(json.loads(out.splitlines()[0]))
        schema = json.loads((root / "docs/schemas/job.schema.json").read_text())
        bake_keys = set(schema["$defs"]["bake"]["properties"])
        missing = sorted(keys - bake_keys)
        check(not missing, f"job.schema.json lacks option keys: {missing}")
        print(f"job.schema.json: all {len(keys)} keys of --print-options present")
    for tool in (["tools/job-schema", str(nmbake), "--check"], ["tools/docs-tables", "--check"]):
        done = subprocess.run([sys.executable, *tool], cwd=root, capture_output=True, text=True)
        print(done.stdout.strip())
        check(done.returncode == 0, f"{' '.join(tool)}: {done.stdout}{done.stderr}")
    for f in failures:
        print("FAIL: " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
