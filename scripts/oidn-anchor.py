#!/usr/bin/env python3
"""Intel Open Image Denoise as the external anchor of `gridlight eval motion`.

The anchor every user compares a viewport with: OIDN 2's RT filter (the denoiser in the
Cycles, V-Ray, Arnold and LuxCore viewports) on a complete low-sample frame, with the
G-buffer's albedo and normal as auxiliary images. gridlight runs this script as a child
process when `python3 -c "import pyoidn"` succeeds; it is never a dependency of the
binary. Set up with:

    pip install pyoidn      # OIDN 2 binaries and a cffi binding, CPU device included

Usage: oidn-anchor.py DIR [--threads N] [--quality high|balanced|fast]

For each NAME-color.pfm in DIR (with NAME-albedo.pfm and NAME-normal.pfm beside it,
linear HDR colour, albedo in [0, 1], world normals in [-1, 1]), writes NAME-out.pfm and
prints one JSON line {"name": NAME, "ms": milliseconds of the filter's execution}.
Device and filter set-up are timed apart (printed once as {"setup_ms": ...}), as a
viewport pays them once.
"""

import argparse
import json
import pathlib
import sys
import time

import numpy as np


def read_pfm(path):
    data = path.read_bytes()
    fields, at = [], 0
    while len(fields) < 4:
        while data[at : at + 1].isspace():
            at += 1
        start = at
        while at < len(data) and not data[at : at + 1].isspace():
            at += 1
        fields.append(data[start:at].decode())
    if fields[0] != "PF":
        sys.exit(f"{path}: not an RGB PFM (magic {fields[0]!r})")
    w, h, scale = int(fields[1]), int(fields[2]), float(fields[3])
    dtype = "<f4" if scale < 0 else ">f4"
    pixels = np.frombuffer(data[at + 1 :], dtype=dtype, count=w * h * 3)
    return np.ascontiguousarray(pixels.reshape(h, w, 3)[::-1], dtype=np.float32)


def write_pfm(path, image):
    h, w, _ = image.shape
    header = f"PF\n{w} {h}\n-1.0\n".encode()
    path.write_bytes(header + np.ascontiguousarray(image[::-1], dtype="<f4").tobytes())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir", type=pathlib.Path)
    parser.add_argument("--threads", type=int, default=0, help="0: every core")
    parser.add_argument("--quality", default="high", choices=["high", "balanced", "fast"])
    args = parser.parse_args()
    import pyoidn

    started = time.perf_counter()
    device = pyoidn.Device(pyoidn.OIDN_DEVICE_TYPE_CPU)
    if args.threads > 0:
        device.set_int("numThreads", args.threads)
    device.commit()
    quality = {
        "high": pyoidn.OIDN_QUALITY_HIGH,
        "balanced": pyoidn.OIDN_QUALITY_BALANCED,
        "fast": pyoidn.OIDN_QUALITY_FAST,
    }[args.quality]
    filt, size = None, None
    print(json.dumps({"setup_ms": (time.perf_counter() - started) * 1e3}), flush=True)
    for color_path in sorted(args.dir.glob("*-color.pfm")):
        name = color_path.name[: -len("-color.pfm")]
        color = read_pfm(color_path)
        albedo = read_pfm(args.dir / f"{name}-albedo.pfm")
        normal = read_pfm(args.dir / f"{name}-normal.pfm")
        out = np.zeros_like(color)
        if filt is None or size != color.shape:
            # A new filter for each size: OIDN sizes its network's buffers at commit.
            filt, size = pyoidn.Filter(device, pyoidn.OIDN_FILTER_TYPE_RT), color.shape
            filt.set_bool("hdr", True)
            filt.set_quality(quality)
        for slot, image in [
            (pyoidn.OIDN_IMAGE_COLOR, color),
            (pyoidn.OIDN_IMAGE_ALBEDO, albedo),
            (pyoidn.OIDN_IMAGE_NORMAL, normal),
            (pyoidn.OIDN_IMAGE_OUTPUT, out),
        ]:
            filt.set_image(slot, image, pyoidn.OIDN_FORMAT_FLOAT3)
        filt.commit()
        started = time.perf_counter()
        filt.execute()
        ms = (time.perf_counter() - started) * 1e3
        error = device.get_error()
        if error:
            sys.exit(f"{color_path}: OIDN failed: {error}")
        write_pfm(args.dir / f"{name}-out.pfm", out)
        print(json.dumps({"name": name, "ms": ms}), flush=True)


if __name__ == "__main__":
    main()
