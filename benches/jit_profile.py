#!/usr/bin/env python3
"""Where a bake's time goes inside lavapipe's compiled shaders: samples a
running bake with `perf`, copies the JIT code out of the process with `gdb`,
disassembles it with `objdump`, and prints each hot stretch of code (from one
`ret` to the next: a shader entry point or one of the texel-fetch helpers it
calls) with its share of the samples and the instructions the samples fall
after (a sample lands on the instruction after the one that stalled).

    python3 benches/jit_profile.py -- target/release/bake room.glb --max-atlas-size 1024 -o /tmp/out
    python3 benches/jit_profile.py --wait 20 --seconds 10 --top 4 -- <any command running wgpu on lavapipe>

Lavapipe's JIT code has no symbols, so `perf report` alone shows bare
addresses. Tell entry points apart by their helpers (a pass that reads the
hemicube depth calls a one-channel fetch) or by changing one shader and
profiling again. Needs `perf` (linux-perf), `gdb` and `objdump` (binutils);
the command is killed after sampling.
"""

import argparse
import collections
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

INSTRUCTION = re.compile(r"\s*([0-9a-f]+):\s+(?:[0-9a-f]{2} )+\s*(\S.*)?")


def sample(pid, seconds, data):
    subprocess.run(["perf", "record", "-q", "-F", "4999", "-p", str(pid), "-o", data, "--", "sleep", str(seconds)],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    script = subprocess.run(["perf", "script", "-i", data, "-F", "ip"], check=True, capture_output=True, text=True)
    return collections.Counter(int(line, 16) for line in script.stdout.split())


def anonymous_code(pid):
    """(start, end) of the process's executable mappings that no file backs: the JIT's."""
    regions = []
    with open(f"/proc/{pid}/maps") as maps:
        for line in maps:
            fields = line.split()
            if "x" in fields[1] and len(fields) == 5:
                start, end = (int(x, 16) for x in fields[0].split("-"))
                regions.append((start, end))
    return regions


def disassemble(pid, regions, folder):
    """Every instruction of `regions` as (address, text), in address order."""
    dumps = [f"--eval-command=dump binary memory {folder}/{start:x}.bin {start:#x} {end:#x}" for start, end in regions]
    subprocess.run(["gdb", "-p", str(pid), "-batch", *dumps], check=True, capture_output=True)
    instructions = []
    for start, _ in regions:
        path = f"{folder}/{start:x}.bin"
        if not os.path.exists(path):
            continue
        listing = subprocess.run(["objdump", "-D", "-b", "binary", "-m", "i386:x86-64", f"--adjust-vma={start:#x}", path],
                                 check=True, capture_output=True, text=True).stdout
        for line in listing.splitlines():
            match = INSTRUCTION.match(line)
            if match and match.group(2):
                instructions.append((int(match.group(1), 16), match.group(2)))
    instructions.sort()
    return instructions


def stretches(instructions, samples):
    """Code from one `ret` to the next, each with the samples in it and, per
    mnemonic, the samples that fell just after one."""
    result, start, count, after = [], None, 0, collections.Counter()
    previous = None
    for address, text in instructions:
        if start is None:
            start, count, after = address, 0, collections.Counter()
        hits = samples.get(address, 0)
        count += hits
        if previous is not None:
            after[previous] += hits
        previous = text.split()[0]
        if previous == "ret":
            result.append((start, address, count, after))
            start, previous = None, None
    return result


def report(regions, instructions, samples, top):
    total = sum(samples.values())
    in_jit = sum(c for ip, c in samples.items() if any(start <= ip < end for start, end in regions))
    print(f"{total} samples, {100 * in_jit / max(total, 1):.1f} % in JIT code\n")
    print("| stretch | bytes | share | hottest instructions (share of the stretch's samples after each) |")
    print("|---|---|---|---|")
    ranked = sorted(stretches(instructions, samples), key=lambda s: -s[2])
    for start, end, count, after in ranked[:top]:
        hottest = ", ".join(f"{m} {100 * c / max(count, 1):.0f} %" for m, c in after.most_common(6))
        print(f"| {start:#x} | {end - start} | {100 * count / max(total, 1):.1f} % | {hottest} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--wait", type=float, default=12.0, help="seconds to let the command start (pipelines, import)")
    parser.add_argument("--seconds", type=float, default=6.0, help="seconds to sample")
    parser.add_argument("--top", type=int, default=8, help="stretches to print")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- then the command to profile")
    args = parser.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("give the command to profile after --")
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        time.sleep(args.wait)
        if process.poll() is not None:
            sys.exit(f"the command ended within --wait {args.wait} s; give it more work or a shorter wait")
        with tempfile.TemporaryDirectory() as folder:
            samples = sample(process.pid, args.seconds, f"{folder}/perf.data")
            regions = anonymous_code(process.pid)
            instructions = disassemble(process.pid, regions, folder)
        report(regions, instructions, samples, args.top)
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()


if __name__ == "__main__":
    main()
