#!/usr/bin/env python3
"""Issue 47, target 4: bake against Blender Cycles, error against seconds.

    pip install bpy matplotlib OpenEXR
    python3 benches/cycles.py --bake target/release/bake           # ~17 min on 2 cores
    python3 benches/cycles.py --bake target/release/bake --quick   # ~1 min, checks it runs
    python3 benches/cycles.py --from-json benches/cycles_results.json  # tables and figures again
    python3 benches/cycles.py --atlas 512 --only emitter_room --reference 1024 --max-samples 256
        # at the README's atlas size: Cycles' cost a sample grows 16-fold, so fewer samples

For each scene bake runs a ladder of settings (the wall time of the whole CLI
run each); bake's output GLB (its TEXCOORD_1 lightmap UVs) is then loaded in
Blender and Cycles bakes the DIFFUSE pass (direct + indirect, no colour) into
the same atlas at 1, 2, 4, ... 1024 samples, until its error is under 0.8 %
(the wall time of the bake operator each). Both are compared with a converged
Cycles bake; see error() for the metric and cycles_bake.py for what Cycles is
told. Prints a table per scene and writes docs/cycles-<scene>.svg.
"""

import argparse
import datetime
import importlib.util
import json
import os
import subprocess
import sys
import time

import numpy as np
import OpenEXR

sys.dont_write_bytecode = True  # no __pycache__ in benches/ for the helpers below
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
# This file's name is Blender's Cycles add-on's: with benches/ on the path bpy
# would import it as the add-on. Take benches/ off and load the helpers by path.
sys.path = [p for p in sys.path if os.path.abspath(p or ".") != HERE]


def helper(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(HERE, f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


cycles_bake = helper("cycles_bake")  # imports bpy
cycles_scene = helper("cycles_scene")
LUMA = np.array([0.2126, 0.7152, 0.0722])
BLOCK = 4

# bake's ladder, cheapest first: fewer environment lights, shadow rays and shooter patches,
# a looser stop, then the defaults, then past them.
LADDER = [
    ["--lights", "64", "--direct-rays", "64", "--patches", "64", "--tolerance", "0.1", "--no-supersample",
     "--no-contact-trace"],
    ["--lights", "64", "--patches", "64", "--tolerance", "0.1", "--no-supersample", "--no-contact-trace"],
    ["--lights", "256", "--direct-rays", "64", "--patches", "256", "--tolerance", "0.03", "--no-supersample",
     "--no-contact-trace"],
    ["--lights", "256", "--patches", "256", "--tolerance", "0.03", "--no-supersample", "--no-contact-trace"],
    ["--lights", "256", "--patches", "256", "--tolerance", "0.03"],
    [],
    ["--lights", "4096", "--patches", "4096", "--tolerance", "0.003"],
]


def scenes(work, env_dir, quick, atlas=None):
    """(name, kind, glb, environment or None, atlas size, reference samples)."""
    # Reference samples from a trial: each scene's own error then ≈ 0.1–1 %.
    default_atlas, samples = (64, 128) if quick else (128, 8192)
    atlas = atlas or default_atlas
    window, emitter = os.path.join(work, "window_room.glb"), os.path.join(work, "emitter_room.glb")
    cycles_scene.window_room(window)
    cycles_scene.emitter_room(emitter)
    sky_sun = os.path.join(ROOT, "fixtures", "sky_sun.exr")
    return [
        ("sphere_on_ground", "open ground under a sun", os.path.join(ROOT, "fixtures", "sphere_on_ground.glb"),
         sky_sun, atlas, samples),
        ("window_room", "closed room lit through a window, colour bleeding", window,
         os.path.join(env_dir, "courtyard.exr"), atlas, samples),
        # Cycles' costliest per sample (0.12 s at 128², 2 threads): half as
        # many put its own error near 0.3 % all the same.
        ("emitter_room", "closed room lit only by an emissive panel", emitter, None, atlas, samples // 2),
    ]


def read_exr(path):
    channels = OpenEXR.File(path).channels()
    return np.asarray(channels["RGB"].pixels, np.float64)


def run_bake(binary, glb, env, atlas, extra, out):
    args = [binary, glb, "--max-atlas-size", str(atlas), "-q", "-o", out, *extra]
    if env:
        args += ["--env", env]
    start = time.monotonic()
    run = subprocess.run(args, capture_output=True, text=True)
    wall = time.monotonic() - start
    if run.returncode != 0:
        sys.exit(f"{' '.join(args)} failed ({run.returncode}):\n{run.stderr}")
    name = os.path.splitext(os.path.basename(glb))[0]
    return wall, read_exr(os.path.join(out, f"{name}.lightmap0.exr")), os.path.join(out, f"{name}.glb")


def blocks(image, mask):
    """Luminance averaged over the masked texels of each 4×4 block; blocks
    with no masked texel are left out."""
    lum = image[..., :3] @ LUMA * mask
    h, w = mask.shape
    ph, pw = -h % BLOCK, -w % BLOCK
    lum = np.pad(lum, ((0, ph), (0, pw)))
    count = np.pad(mask.astype(np.float64), ((0, ph), (0, pw)))
    shape = (lum.shape[0] // BLOCK, BLOCK, lum.shape[1] // BLOCK, BLOCK)
    sums, counts = lum.reshape(shape).sum((1, 3)), count.reshape(shape).sum((1, 3))
    keep = counts > 0
    return sums[keep] / counts[keep]


def error(image, reference, mask):
    """Relative RMSE: sqrt(mean over blocks of (a - r)²) / mean over blocks of r,
    a and r the luminance (Rec. 709 weights) of 4×4-texel blocks averaged over
    the masked texels."""
    a, r = blocks(image, mask), blocks(reference, mask)
    return float(np.sqrt(np.mean((a - r) ** 2)) / np.mean(r))


def with_neighbours(mask):
    """Each texel's value and its eight neighbours' (False past the image's edge)."""
    m = np.pad(mask, 1)
    h, w = mask.shape
    return [m[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)]


def mask_of(written):
    """Texels Cycles wrote (margin 0: texel centres inside a triangle) whose
    eight neighbours it wrote too: the charts' edge texels, where bake's and
    Cycles' footprint conventions differ, are left out."""
    return np.logical_and.reduce(with_neighbours(written))


def beside_hidden(reference, written):
    """Texels the reference leaves black (hidden under something standing on
    the surface, a box's foot on the floor) and their eight neighbours. A
    texel there has its centre at or under the object's foot: Cycles takes
    the light at the centre, bake the mean over the part of the texel's
    footprint in view (issue 6), so the two differ by convention, as at the
    charts' edges."""
    lum = reference[..., :3] @ LUMA
    black = written & (lum < 1e-3 * lum[written].mean())
    return np.logical_or.reduce(with_neighbours(black))


def corrected(raw, noise):
    """The error against the truth: the reference's own (independent) error
    taken out in quadrature."""
    return float(np.sqrt(max(raw * raw - noise * noise, 0.0)))


def extrapolate(runs, threshold):
    """Cycles is unbiased: its error falls as 1/√samples and its time grows
    linearly in samples. From the runs [(samples, seconds, error)], first
    and last (the shortest are mostly setup), the seconds at which the error
    would reach the threshold."""
    (n0, t0, _), (n1, t1, e1) = runs[0], runs[-1]
    n = n1 * (e1 / threshold) ** 2
    return ("~", t1 + (n - n1) * max(t1 - t0, 0.0) / (n1 - n0))


def time_to(curve, threshold):
    """Seconds at which the curve [(seconds, error)] first falls to the
    threshold, interpolated on log-log axes; ('<=', t) when its first point is
    already below; None when never."""
    for i, (t, e) in enumerate(curve):
        if e <= threshold:
            if i == 0:
                return ("<=", t)
            t0, e0 = curve[i - 1]
            f = (np.log(threshold) - np.log(e0)) / (np.log(e) - np.log(e0))
            return ("=", float(np.exp(np.log(t0) + f * (np.log(t) - np.log(t0)))))
    return None


def fmt_time(reached):
    if reached is None:
        return "not reached"
    return {"<=": "≤ ", "~": "~"}.get(reached[0], "") + f"{reached[1]:.1f} s"


def fmt_ratio(cycles, bake):
    if bake is None:
        return "bake does not reach it"
    if cycles is None:
        return "Cycles does not reach it"
    ratio = f"{cycles[1] / bake[1]:.1f}×"
    # An upper bound on bake's time bounds the ratio from below; an
    # extrapolated or bounded time of Cycles' makes it approximate.
    if cycles[0] == "~":
        return "~" + ratio + (" (bake's time an upper bound)" if bake[0] == "<=" else "")
    if cycles[0] == "<=":
        return "undetermined (both below at their first point)" if bake[0] == "<=" else "≤ " + ratio
    return ("≥ " if bake[0] == "<=" else "") + ratio


def figure(path, name, kind, bake_curve, cycles_curve, cycles_extra, noise):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.loglog(*zip(*bake_curve), "o-", label="bake (whole CLI run, settings ladder)")
    line, = ax.loglog(*zip(*cycles_curve), "s-", label="Cycles CPU (bake operator, 1, 2, 4, … samples)")
    if cycles_extra:
        ax.loglog(*zip(cycles_curve[-1], *cycles_extra), ":", color=line.get_color(),
                  label="Cycles extrapolated (error ∝ 1/√samples)")
    # Below about the reference's own error a corrected point is uncertain.
    ax.axhline(noise, color="grey", lw=0.8, ls=":")
    ax.text(min(t for t, _ in bake_curve + cycles_curve), noise * 1.04, "reference's own error",
            color="grey", fontsize=7)
    for level in (0.02, 0.01):
        ax.axhline(level, color="grey", lw=0.8, ls="--")
        ax.text(min(t for t, _ in bake_curve + cycles_curve), level * 1.04,
                f"{level:.0%}", color="grey", fontsize=8)
    ax.set_xlabel("seconds (wall clock, 2 CPU cores)")
    ax.set_ylabel("relative RMSE against the truth\n(4×4-texel blocks' luminance, reference noise taken out)",
                  fontsize=8)
    ax.set_title(f"{name}: {kind}", fontsize=10)
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def measure(args, name, kind, glb, env, atlas, reference_samples, work):
    out = os.path.join(work, name)
    ladder = LADDER[::3] if args.quick else LADDER
    bake_runs = []
    for i, extra in enumerate(ladder):
        wall, lightmap, baked_glb = run_bake(args.bake, glb, env, atlas, extra, os.path.join(out, f"bake{i}"))
        bake_runs.append((" ".join(extra) or "defaults", wall, lightmap))
        print(f"  bake {' '.join(extra) or 'defaults'}: {wall:.1f} s", flush=True)
        if i == 0:
            uv_glb, shape = baked_glb, lightmap.shape
        assert lightmap.shape == shape, "the ladder's runs unwrapped differently"

    session = cycles_bake.Session(uv_glb, env, shape[1], shape[0])
    half = reference_samples // 2
    ref_a, _ = session.bake(half, seed=1)
    ref_b, _ = session.bake(half, seed=2)
    written = mask_of((ref_a[..., 3] > 0) & (ref_b[..., 3] > 0))
    reference = (ref_a + ref_b) / 2
    hidden = beside_hidden(reference, written)
    mask = written & ~hidden
    # The two halves' difference has twice the variance of one half, four
    # times that of their mean: the reference's own error is half of it.
    noise = error(ref_a, ref_b, mask) / 2
    # Kept for comparisons the ladder does not make (a throwaway build against it).
    np.save(os.path.join(out, "reference.npy"), reference)
    np.save(os.path.join(out, "mask.npy"), mask)
    cycles_runs = []
    for i, samples in enumerate(s for s in args.samples if s <= args.max_samples):
        image, wall = session.bake(samples, seed=10 + i)
        raw = error(image[..., :3], reference, mask)
        cycles_runs.append((samples, wall, raw))
        print(f"  Cycles {samples} samples: {wall:.1f} s, {raw:.2%}", flush=True)
        if corrected(raw, noise) < 0.008:
            break  # past 1 %: enough to interpolate

    lit = mask & (reference[..., :3].sum(-1) > 0)
    uncovered = int(sum(((lm[..., :3].sum(-1) == 0) & lit).sum() for _, _, lm in bake_runs))
    return {
        "name": name, "kind": kind, "atlas": f"{shape[1]}×{shape[0]}", "atlas_size": atlas, "texels": int(mask.sum()),
        "beside_hidden": int((written & hidden).sum()),
        "blocks": len(blocks(reference, mask)), "reference_samples": reference_samples, "reference_noise": noise,
        "reference_seconds": session.seconds[:2], "load_seconds": session.load_seconds,
        "uncovered": uncovered, "blender": session.version,
        "bake": [(s, w, error(lm, reference, mask)) for s, w, lm in bake_runs],
        "cycles": cycles_runs,
    }


def report(r, docs):
    print(f"\n## {r['name']} ({r['kind']}), atlas {r['atlas']}, {r['texels']:,} texels compared in "
          f"{r['blocks']:,} blocks" + (f" ({r['beside_hidden']:,} beside texels hidden under an object left out)"
                                        if r.get("beside_hidden") else ""))
    print(f"reference: Cycles {r['reference_samples']} samples ({r['reference_seconds'][0]:.0f} + "
          f"{r['reference_seconds'][1]:.0f} s), its own error ≈ {r['reference_noise']:.3%} "
          f"(half the two halves' difference); Blender load {r['load_seconds']:.1f} s, not counted")
    if r["uncovered"]:
        print(f"note: {r['uncovered']} compared texels are 0 in some bake run where the reference is not")
    noise = r["reference_noise"]
    print("| tool | settings | seconds | rel. RMSE against the reference | against the truth |\n|---|---|---|---|---|")
    for tool in ("bake", "cycles"):
        for settings, wall, err in r[tool]:
            settings = f"{settings} samples" if tool == "cycles" else settings
            print(f"| {tool} | {settings} | {wall:.1f} | {err:.2%} | {corrected(err, noise):.2%} |")
    # A floor of 0.01 % keeps a fully corrected point on the log axes.
    curves = {tool: sorted((w, max(corrected(e, noise), 1e-4)) for _, w, e in r[tool]) for tool in ("bake", "cycles")}
    cycles_runs = [(n, w, corrected(e, noise)) for n, w, e in r["cycles"]]
    r["reached"], extra = {}, []
    for level in (0.02, 0.01):
        b, c = time_to(curves["bake"], level), time_to(curves["cycles"], level)
        if c is None:
            c = extrapolate(cycles_runs, level)
            extra.append((c[1], level))
        r["reached"][f"{level:.0%}"] = (b, c, fmt_ratio(c, b))
        print(f"time to {level:.0%}: bake {fmt_time(b)}, Cycles {fmt_time(c)}, ratio {fmt_ratio(c, b)}")
    # Figures at other than the usual 128² atlas carry its size in their name.
    size = r.get("atlas_size", 128)
    path = os.path.join(docs, f"cycles-{r['name']}.svg" if size == 128 else f"cycles-{r['name']}-{size}.svg")
    figure(path, r["name"], r["kind"], curves["bake"], curves["cycles"], sorted(extra), noise)
    print(f"figure: {os.path.relpath(path, ROOT)}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bake", default=os.path.join(ROOT, "target", "release", "bake"))
    parser.add_argument("--quick", action="store_true", help="64² atlases, few samples: checks the script runs")
    parser.add_argument("--work", default="/tmp/bake-cycles", help="scratch folder for the bakes")
    parser.add_argument("--docs", default=os.path.join(ROOT, "docs"), help="where the figures go")
    parser.add_argument("--env-dir", default=os.path.join(os.path.dirname(ROOT), "shared", "env"),
                        help="the real captured HDRIs (courtyard.exr)")
    parser.add_argument("--reference", type=int, help="Cycles samples of the converged reference (two halves; "
                        "default 4096, 128 with --quick)")
    parser.add_argument("--only", help="one scene by name")
    parser.add_argument("--atlas", type=int, help="the atlas size (default 128, 64 with --quick)")
    parser.add_argument("--max-samples", type=int, default=1024,
                        help="Cycles' most samples a run; past them its times are extrapolated")
    parser.add_argument("--json", help="also write the results here")
    parser.add_argument("--from-json", help="print the tables and draw the figures of results --json wrote")
    args = parser.parse_args()
    if args.from_json:
        with open(args.from_json) as f:
            for r in json.load(f):
                report(r, args.docs)
        return
    args.samples = [1, 4, 16] if args.quick else [2 ** i for i in range(11)]
    os.makedirs(args.work, exist_ok=True)
    version = subprocess.run([args.bake, "--version"], capture_output=True, text=True).stdout.strip()
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"# bake against Cycles, {datetime.datetime.now():%Y-%m-%d %H:%M}; {version} ({args.bake}); "
          f"Blender {cycles_bake.bpy.app.version_string}; {os.cpu_count()} × {cpu}")
    print("error = " + " ".join(error.__doc__.split()))
    results = []
    for name, kind, glb, env, atlas, reference in scenes(args.work, args.env_dir, args.quick, args.atlas):
        if args.only and name != args.only:
            continue
        results.append(measure(args, name, kind, glb, env, atlas, args.reference or reference, args.work))
        report(results[-1], args.docs)
        sys.stdout.flush()
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1, default=str)


if __name__ == "__main__":
    main()
