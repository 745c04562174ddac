#!/usr/bin/env python3
"""Measures our renderer and, when asked, its peers on the dragon scene, then prints one
markdown table of issue 3's targets with ratios measured in the same run. Called by
bench/run.sh, which fetches the data, writes the scenes, builds and installs the peers.

Standard library only (Python 3.11).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
RESOLUTIONS = ["res4", "res3", "res2", "full"]
# bench/README.md: the camera and options every tool uses.
CAMERA_FLAGS = [
    "--width", "1024", "--height", "768", "--fov", "45",
    "--look-from", "0.09,0.21,0.27", "--look-to=-0.005,0.12,-0.005", "--depth", "8",
]  # fmt: skip
EXPECTED_HITS = 573_910
# Generous: a stuck child must not hang the benchmark forever.
CHILD_TIMEOUT_S = 3600


class BenchError(Exception):
    """A step of the benchmark failed; the message says which and why."""


def log(message: str) -> None:
    print(f"bench: {message}", file=sys.stderr, flush=True)


def run_timed(cmd: list[str]) -> tuple[float, float, int, bytes]:
    """Runs `cmd` once: (wall seconds, peak RSS in MB, exit code, stderr)."""
    # stderr goes to a file, not a pipe: a chatty child cannot block on a full pipe.
    with tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        # wait4 gives this child's own rusage, so each run's peak RSS is its own.
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        return wall, usage.ru_maxrss / 1024.0, proc.returncode, err.read()


def whole_process(binary: Path, scene: Path, out: Path, repeat: int) -> dict:
    """Median wall time and peak RSS of `raytracer render` over `repeat` runs."""
    cmd = [str(binary), "render", str(scene), "-o", str(out), *CAMERA_FLAGS]
    walls, rss = [], []
    for _ in range(repeat):
        wall, peak, code, err = run_timed(cmd)
        if code != 0:
            raise BenchError(f"{' '.join(cmd)} exited {code}: {err.decode(errors='replace')[-500:]}")
        walls.append(wall)
        rss.append(peak)
    return {"median_s": statistics.median(walls), "runs_s": walls, "peak_rss_mb": max(rss)}


def bench_available(binary: Path) -> bool:
    """Whether this build has the `bench` subcommand (it is being added on main)."""
    probe = subprocess.run([str(binary), "bench", "--help"], capture_output=True)
    return probe.returncode == 0


def component(binary: Path, scene: Path, repeat: int) -> dict:
    """The JSON object `raytracer bench` prints for `scene`."""
    cmd = [str(binary), "bench", str(scene), *CAMERA_FLAGS, "--repeat", str(repeat)]
    proc = subprocess.run(cmd, capture_output=True, timeout=CHILD_TIMEOUT_S)
    if proc.returncode != 0:
        raise BenchError(f"{' '.join(cmd)} exited {proc.returncode}: {proc.stderr.decode(errors='replace')[-500:]}")
    try:
        return json.loads(proc.stdout)
    except json.JSONDecodeError as err:
        raise BenchError(f"{' '.join(cmd)} printed no JSON object ({err})") from err


def reference_suite(binary: Path, out_dir: Path, repeat: int) -> dict:
    """Median total wall time of the 20 reference cases, one process each."""
    cases_path = REPO / "tests/data/reference/cases.toml"
    with open(cases_path, "rb") as f:
        cases = tomllib.load(f)["case"]
    commands = []
    for case in cases:
        vec = lambda v: ",".join(str(float(x)) for x in v)  # noqa: E731
        commands.append(
            [
                str(binary), "render", str(cases_path.parent / case["scene"]),
                "-o", str(out_dir / f"{case['name']}.png"),
                "--width", str(case["width"]), "--height", str(case["height"]),
                "--fov", str(case["fov_degrees"]),
                f"--look-from={vec(case['look_from'])}", f"--look-to={vec(case['look_to'])}",
                "--depth", str(case["depth"]), "--mode", case["mode"],
            ]  # fmt: skip
        )
    totals = []
    for _ in range(repeat):
        total = 0.0
        for cmd in commands:
            wall, _, code, err = run_timed(cmd)
            if code != 0:
                raise BenchError(f"{' '.join(cmd)} exited {code}: {err.decode(errors='replace')[-500:]}")
            total += wall
        totals.append(total)
    return {"cases": len(commands), "median_s": statistics.median(totals), "runs_s": totals}


def peer(python: str, script: str, args: list[str], env: dict) -> dict:
    """Runs one peer script; its last stdout line is its JSON object."""
    path = REPO / "bench/peers" / script
    log(f"peer {script} ...")
    start = time.perf_counter()
    try:
        proc = subprocess.run(
            [python, str(path), *args], capture_output=True, timeout=CHILD_TIMEOUT_S, env=env
        )
    except subprocess.TimeoutExpired:
        return {"failed": f"timed out after {CHILD_TIMEOUT_S} s"}
    lines = proc.stdout.decode(errors="replace").strip().splitlines()
    if proc.returncode != 0 or not lines:
        tail = proc.stderr.decode(errors="replace").strip().splitlines()[-3:]
        return {"failed": f"exit code {proc.returncode}: {' | '.join(tail)}"}
    try:
        result = json.loads(lines[-1])
    except json.JSONDecodeError:
        return {"failed": f"printed no JSON object: {lines[-1][:200]}"}
    result["process_s"] = round(time.perf_counter() - start, 2)
    return result


def machine() -> dict:
    model = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    commit = subprocess.run(
        ["git", "-C", str(REPO), "describe", "--always", "--dirty"], capture_output=True, text=True
    ).stdout.strip()
    return {
        "date": datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        "nproc": os.cpu_count(),
        "cpu": model,
        "os": platform.platform(),
        "load_average": " ".join(f"{x:.2f}" for x in os.getloadavg()),
        "commit": commit or "unknown",
    }


# ---- Report ----


def fmt(value, digits=1, unit=""):
    if value is None:
        return "n/a"
    return f"{value:,.{digits}f}{unit}"


def ratio(a, b) -> str | None:
    if a is None or b is None or b == 0:
        return None
    return f"{a / b:.2f}x"


def verdict(ok) -> str:
    return "n/a" if ok is None else ("yes" if ok else "**no**")


def get(d: dict | None, key: str):
    return None if not d or "skipped" in d or "failed" in d else d.get(key)


def peer_status(name: str, d: dict | None) -> str | None:
    if d is None:
        return None
    if "skipped" in d:
        return f"{name}: skipped ({d['skipped']})"
    if "failed" in d:
        return f"{name}: failed ({d['failed']})"
    return None


def report(results: dict, repeat: int) -> str:
    m = results["machine"]
    ours = results["ours"]
    proc, comp, ref = ours["process"], ours.get("bench"), ours["reference"]
    peers = results.get("peers", {})
    emb, mit, cyc = peers.get("embree"), peers.get("mitsuba"), peers.get("cycles")

    def s(v):
        return None if v is None else v / 1000.0

    out = [
        f"## Dragon benchmark, {m['date']}",
        "",
        f"Machine: {m['nproc']} cores, {m['cpu']}; load average at start {m['load_average']}; "
        f"commit {m['commit']}; medians of {repeat} runs.",
        "",
        "| what | target | ours | peers, same run | ratio | met |",
        "|---|---|---|---|---|---|",
    ]
    # Whole process.
    mit_total = s(get(mit, "load_render_ms"))
    cyc_total = s(get(cyc, "import_render_ms"))
    peers_txt = "; ".join(
        t
        for t in [
            mit_total and f"Mitsuba {get(mit, 'variant')} load + render {fmt(mit_total, 2, ' s')}",
            cyc_total and f"Cycles import + render {fmt(cyc_total, 2, ' s')}",
        ]
        if t
    )
    ratios = "; ".join(
        t
        for t in [
            mit_total and f"Mitsuba / ours = {ratio(mit_total, proc['median_s'])}",
            cyc_total and f"Cycles / ours = {ratio(cyc_total, proc['median_s'])}",
        ]
        if t
    )
    out.append(
        f"| whole process, full dragon, 1024x768, full mode, depth 8 | <= 0.5 s "
        f"| {fmt(proc['median_s'], 2, ' s')} | {peers_txt or '-'} | {ratios or '-'} "
        f"| {verdict(proc['median_s'] <= 0.5)} |"
    )
    # BVH build.
    build = get(comp, "build_ms")
    e_build = get(emb, "build_ms")
    out.append(
        f"| BVH build, full dragon | <= 200 ms | {fmt(build, 0, ' ms')} "
        f"| {'Embree ' + fmt(e_build, 0, ' ms') if e_build else '-'} "
        f"| {'Embree / ours = ' + ratio(e_build, build) if ratio(e_build, build) else '-'} "
        f"| {verdict(None if build is None else build <= 200)} |"
    )
    # Rays.
    for kind, label in [("primary", "primary rays, closest hit"), ("shadow", "shadow rays, any hit")]:
        ours_rate = get(comp, f"{kind}_mrays_per_s")
        e_rate = get(emb, f"{kind}_mrays_per_s")
        r = None if ours_rate is None or not e_rate else ours_rate / e_rate
        out.append(
            f"| {label}, full dragon | >= 2x Embree | {fmt(ours_rate, 1, ' Mrays/s')} "
            f"| {'Embree ' + fmt(e_rate, 1, ' Mrays/s') if e_rate else '-'} "
            f"| {'ours / Embree = ' + f'{r:.2f}x' if r else '-'} "
            f"| {verdict(None if r is None else r >= 2.0)} |"
        )
    # Parsing.
    parse = get(comp, "parse_mb_per_s")
    m_parse = get(mit, "obj_mb_per_s")
    out.append(
        f"| OBJ parsing, dragon OBJ ({fmt((get(comp, 'file_bytes') or 33_397_819) / 1e6, 1)} MB) "
        f"| >= 300 MB/s | {fmt(parse, 0, ' MB/s')} "
        f"| {'Mitsuba OBJ reader ' + fmt(m_parse, 0, ' MB/s') if m_parse else '-'} "
        f"| {'ours / Mitsuba = ' + ratio(parse, m_parse) if ratio(parse, m_parse) else '-'} "
        f"| {verdict(None if parse is None else parse >= 300)} |"
    )
    # Memory.
    rss = proc["peak_rss_mb"]
    peer_rss = "; ".join(
        f"{n} process {fmt(get(d, 'peak_rss_mb'), 0, ' MB')}"
        for n, d in [("Embree", emb), ("Mitsuba", mit), ("Cycles", cyc)]
        if get(d, "peak_rss_mb")
    )
    out.append(
        f"| peak memory (RSS), full dragon render | <= 150 MB | {fmt(rss, 0, ' MB')} "
        f"| {peer_rss or '-'} | - | {verdict(rss <= 150)} |"
    )
    out.append(
        f"| all {ref['cases']} reference cases, one process each | <= 1 s "
        f"| {fmt(ref['median_s'], 2, ' s')} | - | - | {verdict(ref['median_s'] <= 1.0)} |"
    )
    out.append("")
    out.append(
        "Ratios: for times, peer / ours (above 1 means we are faster); for rates, "
        "ours / peer. Embree's binding builds on all cores but traces rays in one thread."
    )
    notes = [n for n in (peer_status(k, v) for k, v in peers.items()) if n]
    if not comp:
        notes.append(f"ours: component figures n/a ({ours.get('bench_note', 'no bench subcommand')})")
    if notes:
        out += ["", *[f"- {n}" for n in notes]]

    # Workloads.
    out += [
        "",
        "### Same work? (full dragon)",
        "",
        "| | expected | ours | Embree |",
        "|---|---|---|---|",
        f"| primary rays | 786,432 | {fmt(get(comp, 'primary_rays'), 0)} | {fmt(get(emb, 'primary_rays'), 0)} |",
        f"| primary hits | {EXPECTED_HITS:,} | {fmt(get(comp, 'primary_hits'), 0)} | {fmt(get(emb, 'primary_hits'), 0)} |",
        f"| shadow rays | 1,147,820 | {fmt(get(comp, 'shadow_rays'), 0)} | {fmt(get(emb, 'shadow_rays'), 0)} |",
        f"| shadow rays occluded | ~10.4% "
        f"| {pct(get(comp, 'shadow_occluded'), get(comp, 'shadow_rays'))} "
        f"| {pct(get(emb, 'shadow_occluded'), get(emb, 'shadow_rays'))} |",
    ]

    # Components.
    if comp:
        out += [
            "",
            "### Our stages (raytracer bench, full dragon)",
            "",
            "| parse | build | BVH nodes | SAH cost | primary | shadow | full render |",
            "|---|---|---|---|---|---|---|",
            f"| {fmt(get(comp, 'parse_ms'), 0, ' ms')} | {fmt(build, 0, ' ms')} "
            f"| {fmt(get(comp, 'bvh_nodes'), 0)} | {fmt(get(comp, 'sah_cost'), 2)} "
            f"| {fmt(get(comp, 'primary_ms'), 1, ' ms')} | {fmt(get(comp, 'shadow_ms'), 1, ' ms')} "
            f"| {fmt(get(comp, 'render_ms'), 0, ' ms')} |",
        ]

    # Peers in detail.
    if peers:
        out += ["", "### Peers in detail", "", "| peer | version | figures |", "|---|---|---|"]
        for name, d in peers.items():
            if peer_status(name, d):
                out.append(f"| {name} | - | {peer_status(name, d)} |")
                continue
            skip_keys = {"peer", "version", "threads", "variant_note"}
            figures = ", ".join(f"{k} {v}" for k, v in d.items() if k not in skip_keys)
            out.append(f"| {name} | {d.get('version', '-')} | {figures} |")

    # Resolutions.
    out += [
        "",
        "### Growth with mesh size (ours)",
        "",
        "| scene | triangles | parse | BVH build | full render | whole process |",
        "|---|---|---|---|---|---|",
    ]
    for name, row in results["resolutions"].items():
        c = row.get("bench")
        out.append(
            f"| {name} | {fmt(get(c, 'triangles'), 0)} | {fmt(get(c, 'parse_ms'), 0, ' ms')} "
            f"| {fmt(get(c, 'build_ms'), 0, ' ms')} | {fmt(get(c, 'render_ms'), 0, ' ms')} "
            f"| {fmt(row['process']['median_s'], 2, ' s')} |"
        )
    return "\n".join(out) + "\n"


def pct(part, whole) -> str:
    if part is None or not whole:
        return "n/a"
    return f"{100.0 * part / whole:.1f}%"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin", type=Path, required=True, help="the raytracer binary")
    parser.add_argument("--work", type=Path, required=True, help="bench/work (scenes, outputs)")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--res", default=",".join(RESOLUTIONS))
    parser.add_argument("--peers-python", help="run the peers with this interpreter")
    args = parser.parse_args()
    resolutions = [r for r in args.res.split(",") if r]
    if not set(resolutions) <= set(RESOLUTIONS):
        parser.error(f"--res takes a comma-separated list of {', '.join(RESOLUTIONS)}")

    work, repeat = args.work.resolve(), args.repeat
    out_dir = work / "out"
    out_dir.mkdir(parents=True, exist_ok=True)
    full = work / "dragon-full.obj"
    results: dict = {"machine": machine(), "repeat": repeat}

    try:
        log(f"whole process, full dragon ({repeat} runs) ...")
        ours: dict = {"process": whole_process(args.bin, full, out_dir / "dragon-full.png", repeat)}
        have_bench = bench_available(args.bin)
        if have_bench:
            log("raytracer bench, full dragon ...")
            ours["bench"] = component(args.bin, full, repeat)
        else:
            ours["bench_note"] = "this build has no `raytracer bench` subcommand yet"
            log(f"skipping component figures: {ours['bench_note']}")
        log(f"reference cases ({repeat} rounds) ...")
        ours["reference"] = reference_suite(args.bin, out_dir, repeat)
        results["ours"] = ours

        results["resolutions"] = {}
        for name in resolutions:
            scene = work / f"dragon-{name}.obj"
            log(f"resolution {name} ...")
            row = {
                "process": ours["process"]
                if name == "full"
                else whole_process(args.bin, scene, out_dir / f"dragon-{name}.png", repeat)
            }
            if have_bench:
                row["bench"] = ours["bench"] if name == "full" else component(args.bin, scene, repeat)
            results["resolutions"][name] = row
    except (BenchError, subprocess.TimeoutExpired, OSError) as err:
        print(f"bench: error: {err}", file=sys.stderr)
        return 1

    if args.peers_python:
        env = dict(os.environ)
        common = ["--obj", str(full), "--repeat", str(repeat)]
        results["peers"] = {
            "embree": peer(args.peers_python, "embree_bench.py", common, env),
            "mitsuba": peer(
                args.peers_python,
                "mitsuba_bench.py",
                [*common, "--ply", str(work / "dragon_vrip.ply"), "--out", str(out_dir / "mitsuba.png")],
                env,
            ),
            "cycles": peer(
                args.peers_python, "cycles_bench.py", [*common, "--out", str(out_dir / "cycles.png")], env
            ),
        }

    table = report(results, repeat)
    (work / "results.md").write_text(table)
    (work / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    print(table, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
