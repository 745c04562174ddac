#!/usr/bin/env python3
"""Splits a callgrind profile of single rays into the walk's parts by inlining.

    split_costs.py CALLGRIND.OUT BINARY [BINARY ...] --rays N --scheme ours|embree

The profile must come from `valgrind --tool=callgrind --dump-instr=yes
--compress-pos=no --compress-strings=no [--cache-sim=yes] --toggle-collect=...`
(callgrind writes each object's addresses as in its file); each BINARY is an object
with debug info (line tables with inlining). Every instruction's own cost (the
inclusive cost of a call is not counted again) goes to a part by the chain of
functions `addr2line -i` finds it inlined in, innermost first, the first decisive
frame deciding: the leaf test (ours: `nearest_in_leaf`, src/shapes; Embree's
kernels/geometry), the node visits (ours: src/bvh/wide.rs but the ray's set-up;
Embree's kernels/bvh) or the ray's set-up and answer (the rest of our crate; Embree's
kernels/common and the driver). Objects not named, or frames no rule decides (a
library's own code: std, wide, glam, Embree's common/simd), go to "other". Prints
each part's events per ray.
"""
import argparse
import collections
import subprocess


def short(name):
    """A function's last path segment without generics: `a::B<T>::new` -> `new`."""
    depth, out = 0, ""
    for c in name:
        depth += c == "<"
        if depth == 0:
            out += c
        depth -= c == ">"
    return out.split("::")[-1].split("(")[0]


def decide_ours(name, file):
    if "/src/shapes/" in file or short(name) in ("nearest_in_leaf", "nearest_in_mask", "nearest_hit"):
        return "leaf"
    if file.endswith("/src/scene/query.rs") and "{{closure}}" in name:
        return "leaf"
    if file.endswith("/src/bvh/wide.rs"):
        return "setup" if short(name) in ("new", "from_parts") else "node"
    if file.endswith("/src/memory.rs"):
        return None  # prefetch_lines: its caller's
    if "/src/" in file and "/.cargo/" not in file and "/rustc/" not in file:
        return "setup"
    return None


def decide_embree(name, file):
    if "/kernels/geometry/" in file:
        return "leaf"
    if "/kernels/bvh/" in file:
        return "node"
    if "/kernels/common/" in file or file.endswith(".c"):
        return "setup"
    return None


PARTS = {"ours": decide_ours, "embree": decide_embree}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("profile")
    ap.add_argument("objects", nargs="+")
    ap.add_argument("--rays", type=int, required=True)
    ap.add_argument("--scheme", choices=PARTS, required=True)
    ap.add_argument("--by-function", action="store_true",
                    help="also each part by the function of its deciding frame")
    args = ap.parse_args()
    events = None
    costs = collections.defaultdict(lambda: None)  # (object, address) -> list
    ob = None
    skip_next = False
    with open(args.profile) as f:
        for line in f:
            if line.startswith("events:"):
                events = line.split()[1:]
            elif line.startswith("ob="):
                ob = line[3:].strip()
            elif line.startswith("calls="):
                skip_next = True
            elif line[:2] == "0x":
                if skip_next:
                    skip_next = False
                    continue
                parts = line.split()
                addr = int(parts[0], 16)
                values = [int(v) for v in parts[2:]]
                key = (ob, addr)
                old = costs[key]
                if old is None:
                    costs[key] = values + [0] * (len(events) - len(values))
                else:
                    for i, v in enumerate(values):
                        old[i] += v
    by_object = collections.defaultdict(list)
    for (ob, addr) in costs:
        by_object[ob].append(addr)
    totals = collections.defaultdict(lambda: [0] * len(events))
    by_function = collections.defaultdict(lambda: [0] * len(events))
    for ob, addrs in by_object.items():
        match = next((p for p in args.objects if ob.endswith(p) or p.endswith(ob)), None)
        if match is None:
            for a in addrs:
                t = totals["other"]
                for i, v in enumerate(costs[(ob, a)]):
                    t[i] += v
            continue
        out = subprocess.run(
            ["addr2line", "-i", "-f", "-C", "-a", "-e", match] + [hex(a) for a in addrs],
            capture_output=True, text=True, check=True).stdout.splitlines()
        frames = {}
        current = None
        name = None
        for l in out:
            if l.startswith("0x"):
                current = int(l, 16)
                frames[current] = []
                name = None
            elif name is None:
                name = l
            else:
                frames[current].append((name, l.split(":")[0]))
                name = None
        for a in addrs:
            part = "other"
            chain = frames.get(a, [])
            for depth, (name, file) in enumerate(chain):
                decided = PARTS[args.scheme](name, file)
                if decided:
                    part = decided
                    inner = next((short(n) for n, f in chain[:depth + 1]
                                  if PARTS[args.scheme](n, f) is not None or "/bvh/" in f), short(name))
                    t = by_function[(part, inner)]
                    for i, v in enumerate(costs[(ob, a)]):
                        t[i] += v
                    break
            t = totals[part]
            for i, v in enumerate(costs[(ob, a)]):
                t[i] += v
    print("part   " + " ".join(f"{e:>9}" for e in events))
    grand = [0] * len(events)
    for part in ("setup", "node", "leaf", "other"):
        if part in totals:
            t = totals[part]
            grand = [g + v for g, v in zip(grand, t)]
            print(f"{part:6} " + " ".join(f"{v / args.rays:9.2f}" for v in t))
    print("total  " + " ".join(f"{v / args.rays:9.2f}" for v in grand))
    if args.by_function:
        for (part, name), t in sorted(by_function.items(), key=lambda kv: (kv[0][0], -kv[1][0])):
            if t[0] >= args.rays:
                print(f"  {part:6} {name[:40]:40} " + " ".join(f"{v / args.rays:9.2f}" for v in t))


main()
