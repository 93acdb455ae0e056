#!/usr/bin/env bash
# Edit-to-display latency of a scripted orbit (scenes/scripts/orbit.toml) with 2 local workers:
# the headless demo plays the orbit, stats.jsonl holds `edit_latency_ms` per edit and
# `shown_at_ms` per frame; this prints, per run and as medians over the runs, the median
# and 95th percentile latency and the frame period while the camera moves.
#
#   bash scripts/edit-latency.sh [ROUNDS] [-- extra demo flags]
#
# Each round runs the default master and then the one before issue 18
# (`--keep-stale-jobs --sink-in-flight 2`: queued jobs of an outdated view are kept and
# the display hands the sink two frames ahead), alternating so that a shared machine's
# load hits both alike. Needs a release build (or GRIDLIGHT_BIN) and python3.
set -euo pipefail
cd "$(dirname "$0")/.."
ROUNDS="${1:-3}"
shift || true
[ "${1:-}" = "--" ] && shift
EXTRA=("$@")
BIN="${GRIDLIGHT_BIN:-target/release/gridlight}"
[ -x "$BIN" ] || cargo build --release
OUT="$(mktemp -d)"
trap 'rm -rf "$OUT"' EXIT
# The orbit runs from 3 s to 15 s after the start; stop a little after it.
SECONDS_PER_RUN=17

run() { # name flags...
  local name="$1"; shift
  local dir="$OUT/$name"
  rm -rf "$dir"
  # Ctrl-C (SIGINT) ends the demo cleanly, as a user would.
  timeout -s INT "$SECONDS_PER_RUN" "$BIN" demo --headless --workers 2 --frames 100000 \
    --script scenes/scripts/orbit.toml --out "$dir" "$@" "${EXTRA[@]}" >/dev/null 2>&1 || true
  python3 - "$dir/stats.jsonl" "$name" <<'PY'
import json, sys
path, name = sys.argv[1], sys.argv[2]
frames = [json.loads(l) for l in open(path)]
lat = sorted(x for f in frames for x in f.get("edit_latency_ms", []))
def pct(v, p):
    if not v: return None
    k = max(1, -(-len(v) * p // 100))  # nearest rank
    return v[int(k) - 1]
moving = [f["shown_at_ms"] for f in frames if 3000 <= f["shown_at_ms"] <= 15000]
gaps = sorted(b - a for a, b in zip(moving, moving[1:]))
period = pct(gaps, 50)
print(json.dumps({
    "run": name, "edits_shown": len(lat), "frames": len(frames),
    "latency_median_ms": pct(lat, 50), "latency_p95_ms": pct(lat, 95),
    "frame_period_median_ms": period,
    "p95_in_frame_periods": (pct(lat, 95) / period) if lat and period else None,
}))
PY
}

for i in $(seq "$ROUNDS"); do
  run "discard-$i" | tee -a "$OUT/all.jsonl"
  run "before-$i" --keep-stale-jobs --sink-in-flight 2 | tee -a "$OUT/all.jsonl"
done
python3 - "$OUT/all.jsonl" <<'PY'
import json, statistics, sys
runs = [json.loads(l) for l in open(sys.argv[1])]
for kind in ("discard", "before"):
    rs = [r for r in runs if r["run"].startswith(kind) and r["latency_p95_ms"] is not None]
    if not rs: continue
    med = lambda k: statistics.median(r[k] for r in rs)
    print(json.dumps({"master": "default" if kind == "discard" else "before issue 18",
        "runs": len(rs),
        "latency_median_ms": round(med("latency_median_ms"), 1),
        "latency_p95_ms": round(med("latency_p95_ms"), 1),
        "frame_period_median_ms": round(med("frame_period_median_ms"), 1),
        "p95_in_frame_periods": round(med("p95_in_frame_periods"), 2)}))
PY
