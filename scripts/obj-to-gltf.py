#!/usr/bin/env python3
"""Converts an OBJ/MTL scene into a `.glb` through Blender, as a user's exporter would.

Issue 39 asks for a glTF scene of tens of textures and at least 100k triangles for
`gridlight bench trace`; no such model ships in a package this project can fetch, and the
public test assets (Sponza, the bunny …) are OBJ and must not be copied into the
repository. This script makes the glTF outside it:

    /tmp/bpy/bin/python scripts/obj-to-gltf.py OUT.glb IN.obj [IN2.obj ...] [--offset X,Y,Z]

Each OBJ is imported by Blender's OBJ importer (MTL → Principled BSDF: `map_Kd` as base
colour, `map_Bump`/`bump` as a normal-map node where Blender makes one), the files are
placed side by side (`--offset` moves each next file by that much, in the OBJ's units,
Y-up), and Blender's glTF exporter writes one `.glb` with every image embedded. Set up
Blender's Python module once: `python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy`.
"""

import argparse
import sys
import time

import bpy


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    parser = argparse.ArgumentParser(description="OBJ/MTL scenes → one .glb through Blender")
    parser.add_argument("out")
    parser.add_argument("objs", nargs="+")
    parser.add_argument("--offset", default="0,0,0", help="X,Y,Z between successive files")
    args = parser.parse_args(argv)
    step = [float(v) for v in args.offset.split(",")]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    started = time.perf_counter()
    for k, path in enumerate(args.objs):
        before = set(bpy.data.objects)
        bpy.ops.wm.obj_import(filepath=path, forward_axis="NEGATIVE_Z", up_axis="Y")
        for obj in set(bpy.data.objects) - before:
            # Blender is Z-up: the OBJ's (x, y, z) offset is Blender's (x, -z, y).
            obj.location.x += step[0] * k
            obj.location.y -= step[2] * k
            obj.location.z += step[1] * k
    triangles = sum(
        sum(len(p.vertices) - 2 for p in o.data.polygons)
        for o in bpy.data.objects
        if o.type == "MESH"
    )
    bpy.ops.export_scene.gltf(
        filepath=args.out, export_format="GLB", export_apply=True, export_image_format="AUTO"
    )
    print(
        f"{args.out}: {triangles} triangles, {len(bpy.data.images)} images, "
        f"{len(bpy.data.materials)} materials, {time.perf_counter() - started:.1f} s",
        flush=True,
    )


if __name__ == "__main__":
    main()
