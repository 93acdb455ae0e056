#!/usr/bin/env python3
"""Known-answer fixtures for gridlight's in-house FLIP (src/tools/eval/flip.rs).

Makes small image pairs (8-bit sRGB PNGs, so both implementations read the same values),
evaluates LDR-FLIP on them with NVIDIA's reference implementation (the `flip-evaluator`
package, `pip install flip-evaluator`; made with version 1.7) at 67 pixels per degree,
and writes the per-pixel maps and means as JSON beside them. Run once from the repository
root; tests/flip_known_answer.rs compares our FLIP with these files:

    python3 scripts/flip_fixtures.py

It also makes the HDR-FLIP fixtures (tests/fixtures/flip-hdr/): linear, unbounded image
pairs (stored as float32 values in the JSON, as no 8-bit file can hold them), evaluated
with the reference's HDR-FLIP (ACES tone mapper, exposures found from the reference).
"""

import json
from pathlib import Path

import numpy as np
from PIL import Image
import flip_evaluator as flip

OUT = Path("tests/fixtures/flip")
OUT_HDR = Path("tests/fixtures/flip-hdr")
W, H = 40, 30


def pairs():
    rng = np.random.default_rng(15)
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    # A colour gradient and the same with noise.
    grad = np.stack([x / (W - 1), y / (H - 1), 0.5 + 0.4 * np.sin(x / 5.0)], axis=-1)
    yield "gradient-noise", grad, grad + rng.normal(0.0, 0.06, grad.shape)
    # Hard edges (a checkerboard) against a blurred copy: FLIP's feature (edge) term.
    checker = (((x // 5) + (y // 5)) % 2)[..., None] * np.array([0.9, 0.8, 0.7]) + 0.05
    k = np.array([1, 4, 6, 4, 1], dtype=np.float64) / 16.0
    blur = checker.copy()
    for axis in (0, 1):
        blur = np.apply_along_axis(lambda v: np.convolve(np.pad(v, 2, mode="edge"), k, "valid"), axis, blur)
    yield "edges-blur", checker, blur
    # Colour patches against hue-shifted and darkened ones: the colour term.
    patches = np.zeros((H, W, 3))
    for i, c in enumerate([(0.8, 0.1, 0.1), (0.1, 0.7, 0.2), (0.2, 0.3, 0.9), (0.9, 0.9, 0.2)]):
        patches[:, i * W // 4:(i + 1) * W // 4] = c
    shifted = patches[..., [1, 2, 0]] * 0.8 + 0.1
    shifted[: H // 2] = patches[: H // 2]
    yield "patches-shift", patches, shifted
    # A point (a small bright dot) missing: the point detector.
    dots = np.full((H, W, 3), 0.2)
    dots[10:12, 10:12] = 1.0
    dots[20, 30] = 0.9
    yield "dots-missing", dots, np.full((H, W, 3), 0.2)


def hdr_pairs():
    rng = np.random.default_rng(21)
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    # A rendered-looking range: a dim room with a light 50 times brighter, and noise.
    room = np.stack([0.05 + 0.3 * x / W, 0.05 + 0.2 * y / H, np.full_like(x, 0.1)], axis=-1)
    room[5:9, 15:25] = (50.0, 45.0, 40.0)
    yield "room-noise", room, room * np.exp(rng.normal(0.0, 0.25, room.shape))
    # The same scene 20 % brighter everywhere: an exposure (energy) error.
    yield "room-brighter", room, room * 1.2
    # A highlight missing: only the brightest exposures see it fully.
    spot = np.full((H, W, 3), 0.3)
    spot[14:17, 18:21] = 20.0
    yield "highlight-missing", spot, np.full((H, W, 3), 0.3)


def hdr_fixtures():
    OUT_HDR.mkdir(parents=True, exist_ok=True)
    index = []
    for name, ref, test in hdr_pairs():
        r32, t32 = ref.astype(np.float32), test.astype(np.float32)
        err, mean, params = flip.evaluate(
            r32, t32, "HDR", inputsRGB=False, applyMagma=False, computeMeanError=True,
            parameters={"ppd": 67.0},
        )
        err = np.asarray(err, dtype=np.float64).reshape(H, W)
        record = {
            "name": name, "width": W, "height": H, "ppd": 67.0, "mean": float(mean),
            "start_exposure": float(params["startExposure"]),
            "stop_exposure": float(params["stopExposure"]),
            "exposures": int(params["numExposures"]),
            "reference": [float(f"{v:.9g}") for v in r32.ravel()],
            "test": [float(f"{v:.9g}") for v in t32.ravel()],
            "map": [round(float(v), 6) for v in err.ravel()],
            "made_with": "flip-evaluator 1.7, HDR, ACES, linear inputs",
        }
        (OUT_HDR / f"{name}.json").write_text(json.dumps(record))
        index.append(name)
        print(f"{name} (HDR): mean FLIP {mean:.6f}, exposures {params}")
    (OUT_HDR / "index.json").write_text(json.dumps(index))


def to8(img):
    return np.clip(np.round(np.clip(img, 0.0, 1.0) * 255.0), 0, 255).astype(np.uint8)


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    index = []
    for name, ref, test in pairs():
        r8, t8 = to8(ref), to8(test)
        Image.fromarray(r8).save(OUT / f"{name}-reference.png")
        Image.fromarray(t8).save(OUT / f"{name}-test.png")
        err, mean, params = flip.evaluate(
            r8.astype(np.float32) / 255.0, t8.astype(np.float32) / 255.0, "LDR",
            inputsRGB=True, applyMagma=False, computeMeanError=True, parameters={"ppd": 67.0},
        )
        err = np.asarray(err, dtype=np.float64).reshape(H, W)
        record = {
            "name": name, "width": W, "height": H, "ppd": 67.0, "mean": float(mean),
            "map": [round(float(v), 6) for v in err.ravel()],
            "made_with": "flip-evaluator 1.7, LDR, inputsRGB=True",
        }
        (OUT / f"{name}.json").write_text(json.dumps(record))
        index.append(name)
        print(f"{name}: mean FLIP {mean:.6f}")
    (OUT / "index.json").write_text(json.dumps(index))
    hdr_fixtures()


if __name__ == "__main__":
    main()
