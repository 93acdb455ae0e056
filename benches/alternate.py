"""Two or more gridlight builds side by side: `bench trace` runs pinned to one CPU,
alternating build by build within each round, then per scene the medians and the paired
ratios (each round's run over the first build's run in the same round, medianed), which
drift of a shared machine's speed affects less than a ratio of medians.

    python3 benches/alternate.py --rounds 5 --cpu 1 \
        old=/path/to/old/gridlight new=target/release/gridlight \
        newv3=target/release/gridlight:--build,v3

Each build is NAME=BINARY[:EXTRA,ARGS]; the first is the anchor the ratios divide by.
Scenes default to the Cornell box, the bunny and Sponza (the last two need the asset search
path, GRIDLIGHT_ASSETS). One JSON line per run goes to --log when given.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
p.add_argument("builds", nargs="+", help="NAME=BINARY[:EXTRA,ARGS]")
p.add_argument("--rounds", type=int, default=5)
p.add_argument("--cpu", default="1", help="CPU to pin every run to (taskset -c)")
p.add_argument("--runs", type=int, default=3, help="bench trace --runs per process")
p.add_argument("--scenes", default="cornell-box,bunny,sponza")
p.add_argument("--log", help="append one JSON line per run to this file")
args = p.parse_args()

builds = []
for spec in args.builds:
    name, sep, rest = spec.partition("=")
    if not sep or not name or not rest:
        sys.exit(f"alternate.py: build {spec!r} is not NAME=BINARY[:EXTRA,ARGS]")
    binary, _, extra = rest.partition(":")
    builds.append((name, binary, [a for a in extra.split(",") if a]))
if len({b[0] for b in builds}) != len(builds):
    sys.exit("alternate.py: two builds have the same name")
scenes = [s for s in args.scenes.split(",") if s]
# The repository's scenes, wherever the script is run from (binaries are relative to the
# working directory, as the shell gives them).
scene_dir = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes")

runs = {}
log = open(args.log, "a") if args.log else None
for r in range(args.rounds):
    for scene in scenes:
        for name, binary, extra in builds:
            cmd = ["taskset", "-c", args.cpu, binary, "bench", "trace",
                   os.path.join(scene_dir, f"{scene}.toml"),
                   "--json", "--runs", str(args.runs), *extra]
            out = subprocess.run(cmd, capture_output=True, text=True)
            if out.returncode != 0:
                sys.exit(f"alternate.py: {' '.join(cmd)} failed:\n{out.stderr.strip()}")
            d = json.loads(out.stdout.strip().splitlines()[-1])
            row = {"round": r, "scene": scene, "build": name, "kernel": d.get("build"),
                   "samples_per_second_per_core": d["samples_per_second_per_core"]}
            runs.setdefault((scene, name), []).append(row["samples_per_second_per_core"])
            if log:
                log.write(json.dumps(row) + "\n")
                log.flush()
    print(f"round {r + 1} of {args.rounds} done", file=sys.stderr, flush=True)

anchor = builds[0][0]
for scene in scenes:
    line = {"scene": scene}
    for name, _, _ in builds:
        line[name] = round(statistics.median(runs[(scene, name)]))
    for name, _, _ in builds[1:]:
        paired = [x / y for x, y in zip(runs[(scene, name)], runs[(scene, anchor)])]
        line[f"{name}_over_{anchor}"] = round(statistics.median(paired), 3)
    print(json.dumps(line))
