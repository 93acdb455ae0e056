#!/usr/bin/env python3
"""Builds the glTF test scenes in Blender, exports them and renders Cycles references.

Issue 39 checks gridlight's glTF material model against an independent path tracer that
reads glTF: Blender's Cycles. Each scene is made here with the Principled BSDF, exported
with Blender's own glTF exporter (what a Blender user hands gridlight) and rendered by
Cycles on the CPU, without denoiser, clamping or adaptive sampling, with a box pixel
filter and enough samples to converge. `tests/gltf_cycles.rs` renders each `.glb` with
gridlight and bounds the FLIP against the reference.

Set up once (Blender as a Python module, 375 MB, Python 3.11):

    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy

Then, from the repository root:

    /tmp/bpy/bin/python scripts/cycles-reference.py [--samples 2048] [--only NAME]

writes tests/fixtures/gltf/NAME.glb and tests/fixtures/gltf/NAME-cycles.exr (linear
radiance, 160x120, half floats) for every scene below, and prints each render's seconds.

Choices that make the two renderers comparable:
- Principled's microfacet distribution is single-scattering GGX (glTF's BRDF), not
  Blender's default multiscatter GGX;
- lights are exported with `RAW` units (a sun of strength S W/m² is a directional light of
  intensity S, which gridlight reads as irradiance S); only suns, emissive surfaces and the
  world are used, so no unit convention for point lights enters;
- a scene without lights or emitters has a white world of strength 1, which is the sky
  gridlight gives such a glTF file; every other scene has a black world;
- 12 bounces of every kind in Cycles, and the test renders gridlight with max_depth 13.
"""

import argparse
import math
import pathlib
import sys
import time

import bpy

WIDTH, HEIGHT = 160, 120
OUT = pathlib.Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "gltf"


def reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def principled(name, base=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5, **extra):
    """A material with one Principled BSDF; `extra` sets more inputs by name."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Roughness"].default_value = roughness
    for key, value in extra.items():
        bsdf.inputs[key].default_value = value
    return mat


def image(name, size, texel, alpha=False):
    """A packed image whose pixel (x, y) is `texel(u, v)` (RGBA, linear 0..1)."""
    img = bpy.data.images.new(name, size, size, alpha=alpha)
    pixels = []
    for y in range(size):
        for x in range(size):
            pixels.extend(texel((x + 0.5) / size, (y + 0.5) / size))
    img.pixels = pixels
    img.file_format = "PNG"
    img.pack()
    return img


def texture_node(mat, img, non_color=False):
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = img
    if non_color:
        img.colorspace_settings.name = "Non-Color"
    return node


def add(obj_op, material, **kw):
    obj_op(**kw)
    obj = bpy.context.active_object
    obj.data.materials.append(material)
    return obj


def sphere(material, location, radius=0.4):
    obj = add(
        bpy.ops.mesh.primitive_uv_sphere_add,
        material,
        segments=24,
        ring_count=12,
        radius=radius,
        location=location,
    )
    bpy.ops.object.shade_smooth()
    return obj


def plane(material, size, location, rotation=(0, 0, 0)):
    return add(
        bpy.ops.mesh.primitive_plane_add, material, size=size, location=location, rotation=rotation
    )


def camera(location, look_at, fov_deg=40.0):
    cam = bpy.data.cameras.new("camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle = math.radians(fov_deg)
    obj = bpy.data.objects.new("camera", cam)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    direction = (
        look_at[0] - location[0],
        look_at[1] - location[1],
        look_at[2] - location[2],
    )
    from mathutils import Vector

    obj.rotation_euler = Vector(direction).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = obj


def sun(direction_deg, strength):
    light = bpy.data.lights.new("sun", "SUN")
    light.energy = strength
    light.angle = math.radians(0.5)
    obj = bpy.data.objects.new("sun", light)
    bpy.context.scene.collection.objects.link(obj)
    obj.rotation_euler = [math.radians(a) for a in direction_deg]


def world(strength):
    w = bpy.data.worlds.new("world")
    w.use_nodes = True
    background = w.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = strength
    bpy.context.scene.world = w


# Blender is Z-up; the exporter turns it into glTF's Y-up.


def spheres():
    """Metallic (rows, 0 → 1) × roughness (columns, 0.05 → 1) under the white sky."""
    for row, metallic in enumerate([0.0, 0.5, 1.0]):
        for col, roughness in enumerate([0.05, 0.3, 0.6, 1.0]):
            mat = principled(f"m{metallic}-r{roughness}", (0.9, 0.45, 0.2), metallic, roughness)
            sphere(mat, ((col - 1.5) * 0.9, 0, (1 - row) * 0.9 + 1.0))
    plane(principled("ground", (0.5, 0.5, 0.5), roughness=1.0), 12, (0, 0, 0))
    camera((0, -6.5, 1.6), (0, 0, 1.0), 34)
    world(1.0)


def emissive():
    """An emissive sphere (strength 8) lighting a floor and a box; a black world."""
    glow = principled(
        "glow",
        (0.0, 0.0, 0.0),
        roughness=1.0,
        **{"Emission Color": (1.0, 0.8, 0.5, 1.0), "Emission Strength": 8.0},
    )
    sphere(glow, (-0.5, 0, 0.6), 0.35)
    add(bpy.ops.mesh.primitive_cube_add, principled("box", (0.2, 0.5, 0.8), roughness=0.7),
        size=0.7, location=(0.6, 0.3, 0.35))
    plane(principled("floor", (0.7, 0.7, 0.7), roughness=1.0), 8, (0, 0, 0))
    plane(principled("wall", (0.8, 0.3, 0.3), roughness=1.0), 8, (0, 2, 0), (math.radians(90), 0, 0))
    camera((0, -4.0, 2.0), (0, 0.5, 0.4), 40)
    world(0.0)


def glass():
    """A rough-ish glass sphere (transmission 1, IOR 1.5) on a checker floor, white sky."""
    checker = image("checker", 64, lambda u, v: (
        (0.9, 0.9, 0.9, 1) if (int(u * 8) + int(v * 8)) % 2 else (0.1, 0.2, 0.5, 1)))
    floor = principled("floor", roughness=1.0)
    tex = texture_node(floor, checker)
    links = floor.node_tree.links
    links.new(tex.outputs["Color"], floor.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    plane(floor, 6, (0, 0, 0))
    sphere(principled("glass", (1, 1, 1), roughness=0.1,
                      **{"Transmission Weight": 1.0, "IOR": 1.5}), (0, 0, 0.7), 0.7)
    camera((0, -4.5, 2.2), (0, 0, 0.5), 38)
    world(1.0)


def textured():
    """A multi-material model: a base-colour-textured cube, a metallic-roughness-textured
    plate and a plain sphere, lit by a sun."""
    stripes = image("stripes", 64, lambda u, v: (
        (0.85, 0.75, 0.3, 1) if int(u * 6) % 2 else (0.25, 0.6, 0.3, 1)))
    cube_mat = principled("painted", roughness=0.6)
    tex = texture_node(cube_mat, stripes)
    bsdf = cube_mat.node_tree.nodes["Principled BSDF"]
    cube_mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    cube = add(bpy.ops.mesh.primitive_cube_add, cube_mat, size=0.9, location=(-0.7, 0.2, 0.45))
    cube.rotation_euler = (0, 0, math.radians(25))

    # glTF's packing: roughness in G, metallic in B.
    mr = image("metal-rough", 64, lambda u, v: (
        0, 0.15 + 0.8 * u, 1.0 if int(v * 4) % 2 else 0.0, 1))
    plate = principled("plate", (0.8, 0.8, 0.85))
    tex = texture_node(plate, mr, non_color=True)
    split = plate.node_tree.nodes.new("ShaderNodeSeparateColor")
    links = plate.node_tree.links
    bsdf = plate.node_tree.nodes["Principled BSDF"]
    links.new(tex.outputs["Color"], split.inputs["Color"])
    links.new(split.outputs["Green"], bsdf.inputs["Roughness"])
    links.new(split.outputs["Blue"], bsdf.inputs["Metallic"])
    plane(plate, 1.4, (0.7, 0.3, 0.7), (math.radians(80), 0, math.radians(-20)))

    sphere(principled("plastic", (0.7, 0.1, 0.1), roughness=0.25), (0.0, -0.6, 0.3), 0.3)
    plane(principled("ground", (0.6, 0.6, 0.6), roughness=1.0), 10, (0, 0, 0))
    sun((50, 10, 30), 3.0)
    camera((0.5, -4.2, 2.0), (0, 0.2, 0.45), 38)
    world(0.0)


SCENES = {"spheres": spheres, "emissive": emissive, "glass": glass, "textured": textured}


def render_settings(samples):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    for bounces in ["max_bounces", "diffuse_bounces", "glossy_bounces",
                    "transmission_bounces", "volume_bounces", "transparent_max_bounces"]:
        setattr(cycles, bounces, 12)
    cycles.caustics_reflective = True
    cycles.caustics_refractive = True
    cycles.blur_glossy = 0.0
    scene.render.resolution_x = WIDTH
    scene.render.resolution_y = HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "16"
    settings.exr_codec = "ZIP"


def main():
    parser = argparse.ArgumentParser(description="glTF fixtures and their Cycles references")
    parser.add_argument("--samples", type=int, default=2048)
    parser.add_argument("--only", choices=sorted(SCENES))
    args = parser.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else None)
    OUT.mkdir(parents=True, exist_ok=True)
    for name, build in SCENES.items():
        if args.only and name != args.only:
            continue
        reset()
        build()
        # Before the export: the exporter takes the camera's aspect ratio from it.
        render_settings(args.samples)
        bpy.ops.export_scene.gltf(
            filepath=str(OUT / f"{name}.glb"),
            export_format="GLB",
            export_cameras=True,
            export_lights=True,
            export_import_convert_lighting_mode="RAW",
            export_apply=True,
        )
        bpy.context.scene.render.filepath = str(OUT / f"{name}-cycles.exr")
        started = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        print(f"{name}: {time.perf_counter() - started:.1f} s of Cycles at {args.samples} spp",
              flush=True)


if __name__ == "__main__":
    main()
