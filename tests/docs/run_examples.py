#!/usr/bin/env python3
"""Runs every shell example the documentation marks as runnable (ctest
Docs.ExamplesRunHeavy):

  tests/docs/run_examples.py NMBAKE NMBAKE_GEN SOURCE_ROOT

A runnable example is a ```sh block right after a line `<!-- runnable -->`
in README.md or docs/**/*.md (docs/index.md, the README's copy, left
out). Each runs with bash -e in a fresh folder
holding the generated scenes of tests/docs/fixture.py (low.obj, high.ply,
moon_low.obj, body_low.obj, rifle_low.obj, game.obj, job.toml, ...), with
the built nmbake first on PATH. An example that exits non-zero fails the
test, named by its page and line, with its output. Fewer than MIN_EXAMPLES
marked examples fail it too (a marker lost in an edit is noticed).
"""
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fixture  # noqa: E402

MARKER = "<!-- runnable -->"
MIN_EXAMPLES = 20


def examples(root):
    # docs/index.md is the README re-rooted (tools/docs-tables): its examples run once, as the README's.
    pages = [root / "README.md"] + sorted(p for p in (root / "docs").rglob("*.md") if p != root / "docs/index.md")
    found = []
    for page in pages:
        lines = page.read_text().split("\n")
        for i, line in enumerate(lines):
            if line.strip() != MARKER:
                continue
            j = i + 1
            while j < len(lines) and not lines[j].strip():
                j += 1
            if j >= len(lines) or lines[j].strip() not in ("```sh", "```bash"):
                found.append((page.relative_to(root), i + 1, None))
                continue
            indent = len(lines[j]) - len(lines[j].lstrip())  # a block inside a list item
            k = j + 1
            while k < len(lines) and lines[k].strip() != "```":
                k += 1
            code = "\n".join(l[indent:] if l[:indent].isspace() else l for l in lines[j + 1:k])
            found.append((page.relative_to(root), j + 2, code))
    return found


def main():
    nmbake, gen, root = (pathlib.Path(a).resolve() for a in sys.argv[1:4])
    found = examples(root)
    failures = []
    with tempfile.TemporaryDirectory(prefix="nmbake-docs-") as tmp:
        scenes = fixture.prepare(os.path.join(tmp, "scenes"), nmbake, gen, root)
        env = dict(os.environ)
        env["PATH"] = os.pathsep.join([str(nmbake.parent), str(gen.parent), env.get("PATH", "")])
        env.pop("NMBAKE_CACHE", None)
        for n, (page, line, code) in enumerate(found):
            where = f"{page}:{line}"
            if code is None:
                failures.append(f"{where}: {MARKER} is not followed by a ```sh block")
                continue
            folder = os.path.join(tmp, f"example{n}")
            shutil.copytree(scenes, folder)
            done = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", code], cwd=folder, env=env,
                                  capture_output=True, text=True, timeout=600)
            status = "ok" if done.returncode == 0 else f"FAILED (exit {done.returncode})"
            print(f"{where}: {status}", flush=True)
            if done.returncode != 0:
                failures.append(f"{where}: exit {done.returncode}\n--- the example:\n{code}\n--- its output:\n"
                                f"{done.stdout}{done.stderr}")
            shutil.rmtree(folder, ignore_errors=True)
    ran = len(found)
    print(f"docs examples: {ran} runnable examples run, {ran - len(failures)} passed")
    if ran < MIN_EXAMPLES:
        failures.append(f"only {ran} runnable examples are marked (expected at least {MIN_EXAMPLES})")
    for f in failures:
        print("FAIL: " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
