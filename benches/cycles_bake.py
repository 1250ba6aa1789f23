"""Cycles' side of benches/cycles.py: bake's output GLB loaded in headless
Blender (bpy from PyPI), every material made a plain Lambertian one with the
glTF's albedo (and emission), back faces black as bake has them, the
environment as the world, and the DIFFUSE pass (direct + indirect, no colour:
E/π, bake's L_lm) baked on the CPU into one float image over the lightmap
UVs (TEXCOORD_1) that every object shares."""

import json
import struct
import time

import bpy
import numpy as np


def gltf_materials(path):
    """Material name → (albedo RGB, emission RGB) from the GLB's JSON. bake's
    output draws '<name> (baked)' (an unlit preview) by default; the albedo is
    the input's material of that name."""
    with open(path, "rb") as f:
        data = f.read()
    length = struct.unpack("<I", data[12:16])[0]
    gltf = json.loads(data[20:20 + length])
    out = {}
    for m in gltf.get("materials", []):
        pbr = m.get("pbrMetallicRoughness", {})
        assert "baseColorTexture" not in pbr or m["name"].endswith(" (baked)"), "textured albedo: not handled"
        strength = m.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
        emission = [e * strength for e in m.get("emissiveFactor", [0, 0, 0])]
        out[m["name"]] = (pbr.get("baseColorFactor", [1, 1, 1, 1])[:3], emission)
    return out


def lambert(name, albedo, emission, image):
    """Diffuse BSDF (+ emission) on the front, black on the back; the bake
    target image node is the active one."""
    mat = bpy.data.materials.new(f"cycles {name}")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*albedo, 1)
    diffuse.inputs["Roughness"].default_value = 0.0
    front = diffuse.outputs["BSDF"]
    if max(emission) > 0:
        glow = nodes.new("ShaderNodeEmission")
        glow.inputs["Color"].default_value = (*emission, 1)
        glow.inputs["Strength"].default_value = 1.0
        add = nodes.new("ShaderNodeAddShader")
        links.new(front, add.inputs[0])
        links.new(glow.outputs["Emission"], add.inputs[1])
        front = add.outputs["Shader"]
    # bake's surfaces are one-sided: the back absorbs everything and emits nothing.
    black = nodes.new("ShaderNodeBsdfDiffuse")
    black.inputs["Color"].default_value = (0, 0, 0, 1)
    side = nodes.new("ShaderNodeNewGeometry")
    mix = nodes.new("ShaderNodeMixShader")
    links.new(side.outputs["Backfacing"], mix.inputs["Fac"])
    links.new(front, mix.inputs[1])
    links.new(black.outputs["BSDF"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    target = nodes.new("ShaderNodeTexImage")
    target.image = image
    nodes.active = target
    return mat


def world(env):
    """The environment map as an Environment Texture with Blender's default
    mapping: after the glTF import's Y-up → Z-up turn it is bake's convention
    (design.md), checked by the shadows in cycles.py's comparison. None: black."""
    w = bpy.data.worlds.new("env")
    w.use_nodes = True
    nodes, links = w.node_tree.nodes, w.node_tree.links
    background = nodes["Background"]
    if env is None:
        background.inputs["Strength"].default_value = 0.0
    else:
        tex = nodes.new("ShaderNodeTexEnvironment")
        tex.image = bpy.data.images.load(env)
        tex.image.colorspace_settings.name = "Linear Rec.709"
        tex.interpolation = "Closest"  # bake's environment is nearest-pixel too
        links.new(tex.outputs["Color"], background.inputs["Color"])
        background.inputs["Strength"].default_value = 1.0
    return w


class Session:
    """One scene loaded; bake() may be called repeatedly."""

    def __init__(self, glb, env, width, height):
        start = time.monotonic()
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.import_scene.gltf(filepath=glb)
        self.image = bpy.data.images.new("lightmap", width, height, alpha=True, float_buffer=True)
        self.image.colorspace_settings.name = "Non-Color"
        materials, made = gltf_materials(glb), {}
        self.objects = [o for o in bpy.context.scene.objects if o.type == "MESH"]
        for o in self.objects:
            # The importer names glTF's TEXCOORD_n the n-th UV map: bake writes TEXCOORD_1.
            assert len(o.data.uv_layers) >= 2, f"{o.name}: no TEXCOORD_1"
            for slot in o.material_slots:
                name = slot.material.name.removesuffix(" (baked)")
                name = name if name in materials else name.rsplit(".", 1)[0]
                if name not in made:
                    made[name] = lambert(name, *materials[name], self.image)
                slot.material = made[name]
        # One object: Blender bakes each selected object on its own, each with
        # the scene's setup (the environment's importance map) again.
        bpy.ops.object.select_all(action="DESELECT")
        for o in self.objects:
            o.select_set(True)
        bpy.context.view_layer.objects.active = self.objects[0]
        bpy.ops.object.join()
        self.object = bpy.context.view_layer.objects.active
        uvs = self.object.data.uv_layers
        assert [uv.name for uv in uvs][:2] == ["UVMap", "UVMap.001"], [uv.name for uv in uvs]
        uvs.active_index = 1
        uvs[1].active_render = True
        scene = bpy.context.scene
        scene.world = world(env)
        self.configure(scene)
        self.load_seconds = time.monotonic() - start
        self.seconds = []
        self.version = bpy.app.version_string

    @staticmethod
    def configure(scene):
        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.device = "CPU"
        scene.render.threads_mode = "FIXED"
        scene.render.threads = 2
        c.use_denoising = False
        c.use_adaptive_sampling = False
        c.sample_clamp_direct = 0.0
        c.sample_clamp_indirect = 0.0
        # Enough bounces that the answer is the converged radiosity bake solves for.
        c.max_bounces = c.diffuse_bounces = 32
        c.glossy_bounces = c.transmission_bounces = c.volume_bounces = c.transparent_max_bounces = 0
        c.caustics_reflective = c.caustics_refractive = False
        bake = scene.render.bake
        bake.margin = 0
        bake.use_clear = False
        bake.target = "IMAGE_TEXTURES"
        bake.use_pass_direct = bake.use_pass_indirect = True
        bake.use_pass_color = False

    def bake(self, samples, seed):
        """The DIFFUSE pass at this many samples: (H×W×4 array, top row first
        as in bake's EXR, alpha 1 where written; seconds the operator took)."""
        scene = bpy.context.scene
        scene.cycles.samples = samples
        scene.cycles.seed = seed
        self.image.pixels.foreach_set(np.zeros(len(self.image.pixels), np.float32))
        start = time.monotonic()
        bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT", "INDIRECT"}, margin=0, use_clear=False)
        seconds = time.monotonic() - start
        self.seconds.append(seconds)
        pixels = np.empty(len(self.image.pixels), np.float32)
        self.image.pixels.foreach_get(pixels)
        image = pixels.reshape(self.image.size[1], self.image.size[0], 4)[::-1]
        return image.astype(np.float64), seconds
