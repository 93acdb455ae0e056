#!/usr/bin/env bash
# gridlight against Mitsuba 3 on the Cornell box, one core each, alternating runs
# (issue 2): prints one JSON line per run and then the medians.
#
#   pip install mitsuba            # scalar_rgb
#   apt-get install libllvm19      # llvm_ad_rgb (Debian's default LLVM 14 aborts)
#   cargo build --release && bash benches/compare_mitsuba.sh [ROUNDS]
#
# Every renderer is pinned to the same CPU with taskset, so a second core (or a busy
# machine) cannot flatter either side.
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-5}
cpu=${CPU:-0}
llvm=${DRJIT_LIBLLVM_PATH:-$(ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* /usr/lib/llvm-19/lib/libLLVM.so.19* 2>/dev/null | head -1 || true)}
out=$(mktemp)
for _ in $(seq "$rounds"); do
  taskset -c "$cpu" target/release/gridlight bench trace scenes/cornell-box.toml --json \
    | python3 -c 'import json,sys; d=json.loads(sys.stdin.readline()); print(json.dumps({"variant":"gridlight","samples_per_second_per_core":d["samples_per_second_per_core"]}))' | tee -a "$out"
  taskset -c "$cpu" python3 benches/mitsuba_cornell.py scalar_rgb --runs 1 | tee -a "$out"
  if [ -n "$llvm" ]; then
    DRJIT_LIBLLVM_PATH=$llvm taskset -c "$cpu" python3 benches/mitsuba_cornell.py llvm_ad_rgb --runs 1 | tee -a "$out"
  fi
done
python3 - "$out" <<'PY'
import json, statistics, sys
runs = {}
for line in open(sys.argv[1]):
    d = json.loads(line)
    runs.setdefault(d["variant"], []).append(d["samples_per_second_per_core"])
med = {k: statistics.median(v) for k, v in runs.items()}
for k, v in med.items():
    print(json.dumps({"median": k, "samples_per_second_per_core": round(v), "runs": len(runs[k])}))
if "scalar_rgb" in med:
    print(json.dumps({"gridlight_over_scalar": round(med["gridlight"] / med["scalar_rgb"], 3),
                      "gridlight_over_llvm": round(med["gridlight"] / med["llvm_ad_rgb"], 3) if "llvm_ad_rgb" in med else None}))
PY
rm -f "$out"
