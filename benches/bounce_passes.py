#!/usr/bin/env python3
"""Where the bounce pass's time goes: bakes each scene with --time-passes
(the GPU waited on after each pass of every batch, which changes no
result) and prints the seconds of each pass as a markdown table, with the
commit and adapter.

    python3 benches/bounce_passes.py                      # the fixtures, as below
    python3 benches/bounce_passes.py --bake /tmp/bake \\
        --scene "room.glb --max-atlas-size 512 --patches 64"   # any scene, any options

Without --scene: the README's bake (sphere_on_ground, 512², sky_sun), corner
(128², 256 lights) and everything (128²). Builds the release binary unless
--bake names one. About a minute on a 2-core machine without a GPU.
"""

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SKY = "fixtures/sky_sun.exr"
SCENES = [
    f"fixtures/sphere_on_ground.glb --env {SKY} --max-atlas-size 512",
    f"fixtures/corner.glb --env {SKY} --max-atlas-size 128 --lights 256",
    f"fixtures/everything.glb --env {SKY} --max-atlas-size 128",
]


def binary(args):
    if args.bake:
        return os.path.abspath(args.bake)
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    return os.path.join(ROOT, "target", "release", "bake")


def timed_bake(bake, scene, out):
    run = subprocess.run([bake, *shlex.split(scene), "-q", "--time-passes", "-o", out], cwd=ROOT,
                         capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"bake {scene} failed ({run.returncode}):\n{run.stderr}")
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f)


def row(scene, bounce, passes):
    if bounce is None:
        return f"| {scene} | no bounce pass |" + " |" * (len(passes) + 3)
    seconds = {p["pass"]: p["seconds"] for p in bounce["passes"]}
    cells = [f"{seconds.get(p, 0.0):.2f}" for p in passes]
    timed = sum(seconds.values())
    return (f"| {scene} | {bounce['batches']} | {bounce['shots']} | {' | '.join(cells)} | {timed:.2f} | "
            f"{bounce['seconds']:.2f} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bake", help="bake binary (default: build target/release/bake)")
    parser.add_argument("--scene", action="append", help="input and options, as on bake's command line")
    args = parser.parse_args()
    bake = binary(args)
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    bounces = []
    adapter = None
    with tempfile.TemporaryDirectory() as work:
        for n, scene in enumerate(args.scene or SCENES):
            report = timed_bake(bake, scene, os.path.join(work, str(n)))
            adapter = report["adapter"]["name"]
            bounces.append((scene, report["scenes"][0]["bounce"]))
    # The passes' columns in the order the bakes ran them.
    passes = []
    for _, bounce in bounces:
        passes += [p["pass"] for p in (bounce or {}).get("passes", []) if p["pass"] not in passes]
    print(f"commit {head.stdout.strip()}, adapter {adapter}; seconds over the bounce pass, each pass waited for\n")
    print("| scene | batches | shots | " + " | ".join(passes) + " | sum | bounce |")
    print("|---" * (len(passes) + 5) + "|")
    print("\n".join(row(scene, bounce, passes) for scene, bounce in bounces))


if __name__ == "__main__":
    main()
