#!/usr/bin/env python3
"""The "Current figures" at the top of BENCHMARKS.md: the README's bake by
stage, a run of several scenes against a run of each, the fixtures' error
against the CPU path tracer with the solve's time, Table 4's cells at 256² and the direct pass against its bare-kernel
ceiling there (`cargo bench --bench table4`), each with the commit, date
and adapter it ran on.

    python3 benches/current.py            # build, then print the section
    python3 benches/current.py --write    # and replace it in BENCHMARKS.md

--env-dir names the real captured HDRIs (default ../shared/env); fixtures'
own sky_sun is always used. --table4-sizes picks Table 4's atlas sizes
(default 256; 512 and 1024 take far longer without a GPU). Takes about
eleven minutes on a 2-core machine without a GPU.
"""

import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIXTURES = ["corner", "everything", "sphere_on_ground"]


def bake(binary, args, out):
    start = time.monotonic()
    run = subprocess.run([binary, *args, "-o", out], cwd=ROOT, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"bake {' '.join(args)} failed ({run.returncode}):\n{run.stderr}")
    wall = time.monotonic() - start
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f), wall


def commit():
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True, text=True)
    return head.stdout.strip() + (" (with uncommitted changes)" if dirty.stdout.strip() else "")


def stage_table(report, wall):
    scene = report["scenes"][0]
    stages = {s["stage"]: s for s in scene["stages"]}
    rows = ["| stage | seconds | work |", "|---|---|---|"]
    work = {
        "texelize": f"{scene['texels']['covered']:,} texels",
        "solve": "",
    }
    for name, stage in stages.items():
        rows.append(f"| {name} | {stage['seconds']:.2f} | {work.get(name, '')} |")
        if name == "solve":
            d, b, c = scene["direct"], scene["bounce"], scene["contact"]
            rate = d["evaluations"] / max(d["seconds"], 1e-9) / 1e6
            rows.append(
                f"| — direct | {d['seconds']:.2f} | {d['lights']:,} lights, {d['evaluations'] / 1e6:.0f} M texel·light "
                f"pairs ({rate:.0f} M/s), {d['rays'] / 1e6:.1f} M rays |"
            )
            rows.append(f"| — bounce | {b['seconds']:.2f} | {b['shots']:,} shots from {b['patches']:,} patches |")
            rows.append(f"| — contact | {c['seconds']:.2f} | {c['gathered']:,} texels gathered |")
    peak = max(s["memory"]["peak_rss_bytes"] for s in scene["stages"]) / 2**20
    gpu = max(s["memory"]["gpu_peak_bytes"] for s in scene["stages"]) / 2**20
    rows.append(f"| total (report) | {report['total_seconds']:.2f} | wall {wall:.2f} s, peak RSS {peak:.0f} MiB, GPU {gpu:.0f} MiB |")
    return rows


def probe_line(binary, work):
    """The probe stage on the README's scene with a probe every 0.25 m."""
    report, _ = bake(binary, ["fixtures/sphere_on_ground.glb", "--env", "fixtures/sky_sun.exr", "--max-atlas-size",
                              "512", "--probes", "0.25"], os.path.join(work, "probes"))
    p = report["scenes"][0]["probes"]
    rays = p["probes"] * (p["rays"] + p["lights"] + p["punctual_lights"])
    counts = "×".join(str(c) for c in p["grid"]["counts"])
    return (f"**Light probes** (the README's bake with `--probes 0.25`): {counts} = {p['probes']:,} probes "
            f"({p['buried']:,} buried), {p['rays']:,} gather rays and {p['lights']:,} light rays each, "
            f"{p['seconds']:.2f} s ({rays / p['seconds'] / 1e6:.1f} M rays/s).")


def several_line(binary, work):
    """One run of the three fixtures against a run of each alone: a run
    builds each pipeline once (`gpu::built`), so later scenes skip it."""
    args = ["--env", "fixtures/sky_sun.exr", "--max-atlas-size", "64"]
    inputs = [f"fixtures/{f}.glb" for f in FIXTURES]
    report, wall = bake(binary, [*inputs, *args], os.path.join(work, "several"))
    scene_seconds = lambda scene: sum(s["seconds"] for s in scene["stages"])
    together = [scene_seconds(s) for s in report["scenes"]]
    alone, alone_wall = [], 0.0
    for fixture, path in zip(FIXTURES, inputs):
        one, one_wall = bake(binary, [path, *args], os.path.join(work, f"alone-{fixture}"))
        alone.append(scene_seconds(one["scenes"][0]))
        alone_wall += one_wall
    per_scene = ", ".join(f"{f} {t:.2f} s ({a:.2f} s alone)" for f, t, a in zip(FIXTURES, together, alone))
    return (f"**A run of several scenes** (the three fixtures in one run, 64², sky_sun, defaults): {wall:.2f} s wall "
            f"against {alone_wall:.2f} s for a run of each; per scene, import to export: {per_scene}.")


def accuracy_rows(binary, envs, work):
    rows = [
        "| scene | environment | error | reference noise | direct (s) | bounce (s) | solve (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for fixture in FIXTURES:
        for env in envs:
            name = os.path.splitext(os.path.basename(env))[0]
            out = os.path.join(work, f"{fixture}-{name}")
            args = [f"fixtures/{fixture}.glb", "--env", env, "--max-atlas-size", "128", "--lights", "256",
                    "--reference", "512", "--reference-samples", "4096"]
            report, _ = bake(binary, args, out)
            scene = report["scenes"][0]
            ref = scene["reference"]
            solve = next(s["seconds"] for s in scene["stages"] if s["stage"] == "solve")
            rows.append(
                f"| {fixture} | {name} | {ref['error'] * 100:.2f} % | {ref['noise'] * 100:.2f} % | "
                f"{scene['direct']['seconds']:.2f} | {scene['bounce']['seconds']:.2f} | {solve:.2f} |"
            )
            print(rows[-1], file=sys.stderr)
    return rows


TABLE4_LIGHTS = "96,384,1536,6144"


def markdown_table(text, heading):
    """The rows of the first table after `heading` in the bench's output,
    each a dict by column name (the first column of a name)."""
    lines = text[text.index(heading):].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    names = [c.strip() for c in lines[start].strip("|").split("|")]
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows.append({name: cells[i] for i, name in reversed(list(enumerate(names)))})
    return rows


def table4_rows(sizes):
    """Table 4's cells and the direct pass against its ceiling, from one run
    of the table4 bench (it builds itself)."""
    run = subprocess.run(
        ["cargo", "bench", "--quiet", "--bench", "table4", "--", "--only", "grid,ceiling", "--sizes", sizes,
         "--lights", TABLE4_LIGHTS, "--modes", "budget,cube"],
        cwd=ROOT, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"the table4 bench failed ({run.returncode}):\n{run.stderr[-4000:]}")
    header = run.stdout.splitlines()[2]
    cells = markdown_table(run.stdout, "## Table 4\n")
    ceiling = markdown_table(run.stdout, "## Direct pass against its bare-kernel ceiling")
    lines = [
        f"**Table 4** (`cargo bench --bench table4 -- --only grid,ceiling --sizes {sizes} --lights {TABLE4_LIGHTS} "
        f"--modes budget,cube`; {header.split('; ', 2)[2]}). Ours: light extraction, unwrap, texelize and solve; "
        "error against 256 texels × 16,384 paths of the CPU path tracer:",
        "",
        "| lights | mode | atlas | paper (s) | ours (s) | ours / paper | direct (s) | bounce (s) | shots | error |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in cells:
        lines.append(f"| {c['lights']} | {c['mode']} | {c['atlas']} | {c['paper']} | {c['ours']} | "
                     f"{c['ours/paper']} | {c['direct']} | {c['bounce']} | {c['shots']} | {c['error']} |")
    lines += [
        "",
        "**The direct pass against its bare-kernel ceiling** in the same cells (`benches/table4/ceiling.rs`): the "
        "light loop alone (each pair's cosine and power) plus the pass's own walks through the hierarchy at the "
        "rate of a bare walk kernel with every lane busy:",
        "",
        "| lights | mode | atlas | pairs (M) | rays (M) | visits per ray | direct (s) | M pairs/s | ceiling (s) | "
        "ceiling M pairs/s | direct / ceiling |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in ceiling:
        lines.append(f"| {c['lights']} | {c['mode']} | {c['atlas']} | {c['pairs (M)']} | {c['rays (M)']} | "
                     f"{c['visits per ray']} | {c['direct (s)']} | {c['M pairs/s']} | {c['ceiling (s)']} | "
                     f"{c['ceiling M pairs/s']} | {c['direct / ceiling']} |")
    return lines + [""]


def section(binary, env_dir, table4_sizes):
    envs = ["fixtures/sky_sun.exr"]
    if os.path.isdir(env_dir):
        envs += sorted(os.path.join(env_dir, e) for e in os.listdir(env_dir) if e.endswith(".exr"))
    with tempfile.TemporaryDirectory() as work:
        readme, wall = bake(binary, ["fixtures/sphere_on_ground.glb", "--env", "fixtures/sky_sun.exr",
                                     "--max-atlas-size", "512"], os.path.join(work, "readme"))
        adapter = readme["adapter"]
        lines = [
            "## Current figures",
            "",
            f"Regenerated by `python3 benches/current.py --write`: commit {commit()}, "
            f"{datetime.date.today().isoformat()}, adapter `{adapter['name']}` ({adapter['backend']}, "
            f"{adapter['driver']}).",
            "",
            "**The README's bake** (sphere_on_ground, 512² atlas, sky_sun, 1,024 lights), by stage:",
            "",
            *stage_table(readme, wall),
            "",
            probe_line(binary, work),
            "",
            several_line(binary, work),
            "",
            "**Error against the CPU path tracer** (each fixture at 128², 256 lights; relative RMSE over 512 texels "
            "× 4,096 paths, `--reference 512 --reference-samples 4096`):",
            "",
            *accuracy_rows(binary, envs, work),
            "",
            *table4_rows(table4_sizes),
            *cycles_rows([os.path.join(ROOT, "benches", name) for name in ("cycles_results.json",
                                                                           "cycles_results_512.json")]),
        ]
    return "\n".join(lines)


def cycles_rows(paths):
    """The times to 2 % and 1 % against Blender Cycles from the last runs of
    benches/cycles.py (35 min at 128², as long a scene at 512², so not rerun
    here), one row a scene and atlas."""
    results = []
    for path in paths:
        if os.path.exists(path):
            with open(path) as f:
                results += [(os.path.relpath(path, ROOT), r) for r in json.load(f)]
    if not results:
        return []
    mark = {"<=": "≤ ", "~": "~", "=": ""}
    when = lambda t: "not reached" if t is None else f"{mark[t[0]]}{t[1]:.1f} s"
    sources = ", ".join(f"`{p}`" for p in dict.fromkeys(p for p, _ in results))
    lines = [
        "**Against Blender Cycles** (time to reach a relative RMSE against a converged Cycles bake; from "
        f"{sources}, the last runs of `benches/cycles.py`; their commits are in the newest sections below that "
        "name them, the method and caveats in \"bake against Blender Cycles\"):",
        "",
        "| scene | atlas | bake to 2 % | Cycles to 2 % | ratio | bake to 1 % | Cycles to 1 % | ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for _, r in results:
        cells = [cell for level in ("2%", "1%") for cell in
                 (when(r["reached"][level][0]), when(r["reached"][level][1]), r["reached"][level][2])]
        lines.append(f"| {r['name']} ({r['kind']}) | {r['atlas']} | " + " | ".join(cells) + " |")
    return lines + [""]


def write(text):
    path = os.path.join(ROOT, "BENCHMARKS.md")
    with open(path) as f:
        old = f.read()
    start = old.find("## Current figures")
    if start < 0:
        start = old.find("\n## ") + 1
        end = start
    else:
        end = old.find("\n## ", start + 1) + 1
    with open(path, "w") as f:
        f.write(old[:start] + text + "\n" + old[end:])


def build():
    """This checkout's release binary, built first: the section names the
    checked-out commit, so it must not measure a binary left from another."""
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    return os.path.join(ROOT, "target/release/bake")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", help="a bake binary to measure (default: build this checkout's release binary)")
    parser.add_argument("--env-dir", default=os.path.join(ROOT, "../shared/env"))
    parser.add_argument("--table4-sizes", default="256", help="Table 4's atlas sizes, comma-separated")
    parser.add_argument("--write", action="store_true", help="replace the section in BENCHMARKS.md")
    args = parser.parse_args()
    binary = args.bin or build()
    text = section(binary, args.env_dir, args.table4_sizes)
    print(text)
    if args.write:
        write(text)


if __name__ == "__main__":
    main()
