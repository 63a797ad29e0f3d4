"""Where a ray query's instructions go in hsr's interleaved walk (``trace_range``),
counted by valgrind, which this VM's noise cannot move: per ray, the instructions,
conditional branches and branches a simple predictor misses, in total and by block of
the compiled walk (a run of instructions executed equally often), with the code of the
heaviest blocks.

    python benchmarks/profile_walk.py [--src SRC ...] [--model M] [--set inside|random]
        [--query cast|occluded|count] [--rays 50000] [--repeat 4] [--blocks 12] [--native]

Each ``--src`` (a checkout's ``src`` folder; default this one's) runs in a process of
its own under ``valgrind --tool=callgrind --branch-sim=yes --dump-instr=yes``, one thread;
the query runs ``--repeat`` times on ``--rays`` rays of ``bench_rays.py``'s sets, so two
checkouts give comparable counts (e.g. a change against its base, in a ``git worktree``).
Under valgrind Numba compiles for the CPU valgrind shows (AVX2, no AVX-512): each eight
float64 lanes are two registers where AVX-512 machines use one. Needs valgrind and, for
the code of the blocks, objdump (Debian's valgrind and binutils). A minute or more a
source: the JIT compiles under valgrind. Runs on demand, never in the test suite.

``--native`` samples time instead, on this CPU's own code (AVX-512 where it has it):
``perf record -e cpu-clock`` (the kernel's software clock, which works where a VM has
no hardware counters; Debian's linux-perf), the samples that land in the compiled walk
grouped into runs of instructions that end at a jump, each with its share of the walk's
samples and the instruction most of them landed on (a long wait shows there, or just
after it). Defaults then 1M rays, 10 times."""

from __future__ import annotations

import argparse
import collections
import ctypes
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
BUNNY = os.path.join(HERE, "..", "..", "shared", "models", "stanford-bunny.obj")


def child(args) -> None:
    """Under valgrind: run the query, then write where the compiled walk lies and its
    bytes (for the disassembly) to ``args.out``."""
    sys.path.insert(0, args.child)
    sys.path.insert(1, HERE)
    from bench_rays import ray_sets

    import hsr
    from hsr.algorithms.bvh.walk import trace_range

    # An editable install of another checkout would otherwise be profiled in its place.
    if not os.path.abspath(hsr.__file__).startswith(os.path.abspath(args.child) + os.sep):
        raise SystemExit(f"hsr was imported from {hsr.__file__}, not from {args.child}")
    mesh = hsr.load(args.model)
    origins, directions = ray_sets(mesh, args.rays, np.random.default_rng(0),
                                   (args.set,))[args.set]
    scene = hsr.RayScene(mesh, threads=1)
    query = getattr(scene, args.query)
    query(origins[:10], directions[:10])  # compiles
    for _ in range(args.repeat):
        query(origins, directions)
    regions = []
    with open("/proc/self/maps") as f:
        maps = [line.split()[0].split("-") for line in f]
    for result in trace_range.overloads.values():
        address = result.library.get_pointer_to_function(result.fndesc.llvm_func_name)
        for start, end in ((int(a, 16), int(b, 16)) for a, b in maps):
            if start <= address < end:
                code = os.path.join(os.path.dirname(args.out), f"code_{start:x}.bin")
                with open(code, "wb") as f:
                    f.write(ctypes.string_at(start, end - start))
                regions.append([start, end, code])
    with open(args.out, "w") as f:
        json.dump({"regions": regions, "rays": args.rays * args.repeat}, f)


def costs(callgrind_out, start, end):
    """{address: [Ir, Bc, Bcm]} of the instructions in [start, end), from a callgrind
    file written with --dump-instr=yes (positions ``instr line``, each relative to the
    last one when it starts with + or -; a call's line after ``calls=`` is the callee's
    inclusive cost, not this instruction's)."""
    counts = collections.defaultdict(lambda: [0, 0, 0])
    position, after_call = 0, False
    with open(callgrind_out) as f:
        for line in f:
            if line[0] in "0123456789+-*":
                fields = line.split()
                p = fields[0]
                if p.startswith("0x"):
                    position = int(p, 16)
                elif p[0] in "+-":
                    position += int(p)
                elif p != "*":
                    position = int(p)
                if after_call:
                    after_call = False
                elif start <= position < end:
                    events = [int(x) for x in fields[2:]] + [0, 0, 0]
                    ir, bc, bcm = events[0], events[1], events[2]
                    cell = counts[position]
                    cell[0] += ir
                    cell[1] += bc
                    cell[2] += bcm
            elif line.startswith("calls="):
                after_call = True
    return counts


def disassembly(code, start):
    """{address: instruction text} of the dumped code, or {} without objdump (said on
    stderr: the tables then lack the blocks' code)."""
    if shutil.which("objdump") is None:
        print("profile_walk.py: no objdump (apt-get install binutils): the blocks' code "
              "is left out", file=sys.stderr)
        return {}
    text = subprocess.run(["objdump", "-D", "-b", "binary", "-m", "i386:x86-64",
                           f"--adjust-vma={start:#x}", code], capture_output=True,
                          text=True, check=True).stdout
    found = (re.match(r"\s*([0-9a-f]+):\s+(?:[0-9a-f]{2} )+\s*(.*)", line)
             for line in text.splitlines())
    # (A long instruction's bytes go on over a second line, which has no text.)
    return {int(m.group(1), 16): m.group(2).strip() for m in found if m and m.group(2).strip()}


def blocks(counts, rays):
    """Runs of consecutive executed instructions with the same execution count:
    (first address, executions a ray, instructions, Ir a ray, Bcm a ray)."""
    runs = []
    for address in sorted(counts):
        ir, _, bcm = counts[address]
        if ir == 0:
            continue
        if runs and runs[-1][5] == ir and address - runs[-1][6] < 16:
            run = runs[-1]
            run[2] += 1
            run[3] += ir / rays
            run[4] += bcm / rays
            run[6] = address
        else:
            runs.append([address, ir / rays, 1, ir / rays, bcm / rays, ir, address])
    return [tuple(r[:5]) for r in runs]


def child_command(src, args, out):
    """The command line of the child process that runs the query for ``src``."""
    return [sys.executable, __file__, "--child", src, "--out", out, "--model", args.model,
            "--set", args.set, "--query", args.query, "--rays", str(args.rays), "--repeat",
            str(args.repeat)]


def runs(code_at):
    """The dumped code's instructions (sorted addresses) cut after each jump or return:
    runs that execute start to end."""
    cut, run = [], []
    for address in sorted(code_at):
        run.append(address)
        if code_at[address].startswith(("j", "ret")):
            cut.append(run)
            run = []
    return cut + ([run] if run else [])


def profile_native(src, args):
    """Run the query for checkout ``src`` under ``perf record`` and print where the
    walk's time samples land; the child's last line of error when it fails, else
    None."""
    with tempfile.TemporaryDirectory() as tmp:
        out, data = os.path.join(tmp, "walk.json"), os.path.join(tmp, "perf.data")
        command = ["perf", "record", "-q", "-e", "cpu-clock", "-F", "20000", "-o", data,
                   "--"] + child_command(src, args, out)
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0 or not os.path.exists(out):
            return f"{src}: {(done.stderr.strip().splitlines() or ['failed'])[-1]}"
        script = subprocess.run(["perf", "script", "-i", data, "-F", "ip"],
                                capture_output=True, text=True)
        samples = collections.Counter(int(line, 16) for line in script.stdout.split())
        with open(out) as f:
            walked = json.load(f)
        print(f"\n{src}: {args.query}, {args.set} rays ({walked['rays']:,} walked), "
              f"native code, time samples")
        for start, end, code in walked["regions"]:
            inside = {a: c for a, c in samples.items() if start <= a < end}
            total = sum(inside.values())
            if total == 0:
                continue
            print(f"{total:,} samples in the walk, {100 * total / sum(samples.values()):.0f}% "
                  f"of the process's (the rest: loading, compiling, making the rays)")
            code_at = disassembly(code, start)
            print("| run | share of the walk | instructions | most samples on | "
                  "its first instructions |")
            print("|---|---|---|---|---|")
            found = [(sum(inside.get(a, 0) for a in run), run) for run in runs(code_at)]
            for count, run in sorted(found, key=lambda f: -f[0])[:args.blocks]:
                if count == 0:
                    break
                top = max(run, key=lambda a: inside.get(a, 0))
                head = "; ".join(code_at[a] for a in run[:3])
                print(f"| {run[0] - start:#x} | {100 * count / total:.1f}% | {len(run)} | "
                      f"{top - start:#x} {code_at[top]} "
                      f"({100 * inside.get(top, 0) / total:.1f}%) | {head} |")
    return None


def profile(src, args):
    """Run the query for checkout ``src`` under valgrind and print its counts; the
    child's last line of error when it fails, else None."""
    with tempfile.TemporaryDirectory() as tmp:
        out, trace = os.path.join(tmp, "walk.json"), os.path.join(tmp, "callgrind.out")
        command = ["valgrind", "--tool=callgrind", "--branch-sim=yes", "--dump-instr=yes",
                   f"--callgrind-out-file={trace}", f"--log-file={trace}.log"]
        command += child_command(src, args, out)
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            return f"{src}: {(done.stderr.strip().splitlines() or ['failed'])[-1]}"
        with open(out) as f:
            walked = json.load(f)
        rays = walked["rays"]
        print(f"\n{src}: {args.query}, {args.set} rays ({rays:,} walked)")
        for start, end, code in walked["regions"]:
            counts = costs(trace, start, end)
            ir, bc, bcm = (sum(c[k] for c in counts.values()) / rays for k in range(3))
            if ir == 0:
                continue
            print(f"per ray: {ir:.1f} instructions, {bc:.2f} conditional branches, "
                  f"{bcm:.2f} mispredicted (valgrind's predictor)")
            code_at = disassembly(code, start)
            addresses = sorted(code_at)
            print("| block | executions a ray | instructions | a ray | mispredicted a ray "
                  "| its first instructions |")
            print("|---|---|---|---|---|---|")
            for first, rate, n, per_ray, missed in sorted(
                    blocks(counts, rays), key=lambda b: -b[3])[:args.blocks]:
                at = addresses.index(first) if first in code_at else len(addresses)
                head = "; ".join(code_at[a] for a in addresses[at:at + 3])
                print(f"| {first - start:#x} | {rate:.2f} | {n} | {per_ray:.1f} | "
                      f"{missed:.2f} | {head} |")
    return None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--src", action="append",
                        help="a checkout's src folder (repeatable; default this one's)")
    parser.add_argument("--model", default=BUNNY)
    parser.add_argument("--set", choices=("inside", "random"), default="inside")
    parser.add_argument("--query", choices=("cast", "occluded", "count"), default="cast")
    parser.add_argument("--rays", type=int, help="default 50000 (1000000 with --native)")
    parser.add_argument("--repeat", type=int, help="default 4 (10 with --native)")
    parser.add_argument("--blocks", type=int, default=12)
    parser.add_argument("--native", action="store_true",
                        help="sample time with perf on the native code instead")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(args)
        return 0
    if args.rays is None:
        args.rays = 1_000_000 if args.native else 50_000
    if args.repeat is None:
        args.repeat = 10 if args.native else 4
    tool, package = ("perf", "linux-perf") if args.native else ("valgrind", "valgrind")
    if shutil.which(tool) is None:
        print(f"profile_walk.py needs {tool} (apt-get install {package})", file=sys.stderr)
        return 2
    for src in args.src or [os.path.join(HERE, "..", "src")]:
        problem = (profile_native if args.native else profile)(os.path.abspath(src), args)
        if problem:
            print(f"profile_walk.py: {problem}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
