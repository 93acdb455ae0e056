"""Mitsuba 3 on its built-in Cornell box, as `gridlight bench trace` measures gridlight.

640x480, 4 spp, `path` integrator with max_depth 5, box pixel filter, one thread
(pinned with `taskset -c 0` by benches/compare_mitsuba.sh). Prints one JSON line:
{"variant", "samples_per_second_per_core", "seconds"}; the median of `--runs`
renders after one warm-up render (which also JIT-compiles the llvm variant).

    pip install mitsuba
    python3 benches/mitsuba_cornell.py scalar_rgb
    DRJIT_LIBLLVM_PATH=/usr/lib/llvm-19/lib/libLLVM.so.19.1 python3 benches/mitsuba_cornell.py llvm_ad_rgb
"""

import argparse
import json
import statistics
import time

import drjit as dr
import mitsuba as mi

p = argparse.ArgumentParser()
p.add_argument("variant", choices=["scalar_rgb", "llvm_ad_rgb"])
p.add_argument("--runs", type=int, default=3)
args = p.parse_args()

mi.set_variant(args.variant)
dr.set_thread_count(1)
scene_dict = mi.cornell_box()
scene_dict["integrator"] = {"type": "path", "max_depth": 5}
film = scene_dict["sensor"]["film"]
film.update({"width": 640, "height": 480, "rfilter": {"type": "box"}})
scene_dict["sensor"]["sampler"] = {"type": "independent", "sample_count": 4}
scene = mi.load_dict(scene_dict)

def render(seed):
    t = time.perf_counter()
    img = mi.render(scene, spp=4, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    return time.perf_counter() - t

render(0)
times = [render(k + 1) for k in range(args.runs)]
seconds = statistics.median(times)
samples = 640 * 480 * 4
print(json.dumps({"variant": args.variant, "samples_per_second_per_core": samples / seconds, "seconds": seconds}))
