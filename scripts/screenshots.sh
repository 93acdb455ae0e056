#!/usr/bin/env bash
# Makes the README's pictures under docs/images/: a screenshot of the demo window on a
# virtual X display (Xvfb, Mesa's software Vulkan), and a render of each built-in scene,
# saved as JPEGs so that the committed pictures stay a few hundred KB in all.
#
#   bash scripts/screenshots.sh [SPP]
#
# Needs Xvfb and xwd (apt-get install xvfb x11-apps mesa-vulkan-drivers), python3 with
# Pillow (pip install Pillow) and a build of gridlight (GRIDLIGHT_BIN, default the release
# build). The window is the real `gridlight demo` with two local workers, stopped with
# Ctrl-C (SIGINT) once its picture has refined for a while.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP="${1:-64}"
BIN="${GRIDLIGHT_BIN:-target/release/gridlight}"
[ -x "$BIN" ] || cargo build --release
python3 -c 'import PIL' 2>/dev/null || { echo "screenshots.sh needs Pillow: pip install Pillow" >&2; exit 1; }
# PNG in, JPEG out (quality JPEG_QUALITY, default 85).
jpeg() {
  python3 -c 'import sys; from PIL import Image
Image.open(sys.argv[1]).convert("RGB").save(sys.argv[2], quality=int(sys.argv[3]), optimize=True, progressive=True)' \
    "$1" "$2" "${JPEG_QUALITY:-85}"
}
OUT=docs/images
mkdir -p "$OUT"
TMP="$(mktemp -d)"
DISPLAY_NO=$((200 + $$ % 300))
cleanup() {
  [ -n "${DEMO:-}" ] && kill -INT "$DEMO" 2>/dev/null || true
  [ -n "${XVFB:-}" ] && kill "$XVFB" 2>/dev/null || true
  rm -rf "$TMP"
}
trap cleanup EXIT

Xvfb ":$DISPLAY_NO" -screen 0 1280x800x24 -nolisten tcp >/dev/null 2>&1 &
XVFB=$!
for _ in $(seq 100); do [ -e "/tmp/.X11-unix/X$DISPLAY_NO" ] && break; sleep 0.1; done

# The window: the built-in Cornell box, from a directory without scene files.
(cd "$TMP" && DISPLAY=":$DISPLAY_NO" NODEVICE_SELECT=1 GRIDLIGHT_PANEL_PROBE="$TMP/panel.json" \
  exec "$OLDPWD/$BIN" demo --workers 2 --out "$TMP/out" >"$TMP/demo.log" 2>&1) &
DEMO=$!
for _ in $(seq 600); do [ -s "$TMP/panel.json" ] && break; sleep 0.1; done
sleep "${SHOT_AFTER_S:-30}" # let frames arrive and accumulate
SIZE=$(python3 -c 'import json,sys; w,h=json.load(open(sys.argv[1]))["window"]; print(f"{w}x{h}")' "$TMP/panel.json")
xwd -root -silent -display ":$DISPLAY_NO" >"$TMP/screen.xwd"
python3 scripts/xwd2png.py "$TMP/screen.xwd" "$TMP/window.png" "$SIZE"
jpeg "$TMP/window.png" "$OUT/window.jpg"
kill -INT "$DEMO"
wait "$DEMO" || true
DEMO=
echo "wrote $OUT/window.jpg ($SIZE); the demo said: $(tail -n 1 "$TMP/demo.log")"

# A render of each built-in scene.
for scene in $("$BIN" scenes | awk '/^built-in/ {b=1; next} /^scene files/ {b=0} b {print $1}'); do
  "$BIN" render "$scene" --spp "$SPP" --quiet --out "$TMP/$scene.png"
  jpeg "$TMP/$scene.png" "$OUT/$scene.jpg"
  echo "wrote $OUT/$scene.jpg"
done
