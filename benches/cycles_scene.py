"""Scenes for benches/cycles.py that the fixtures lack, written as GLB at run
time: a closed room lit through a window (colour bleeding) and a closed room
lit only by an emissive ceiling panel; and, for timing the direct pass on a
dense mesh, a rolling terrain. glTF world, +Y up, metres; every room
surface is a one-sided quad facing into the room (bake and Cycles' material
in cycles.py both treat back faces as black, light-blocking surfaces)."""

import json
import struct

import numpy as np


class Glb:
    """One node per object, one primitive per mesh, factor-only materials."""

    def __init__(self):
        self.bin = bytearray()
        self.gltf = {"asset": {"version": "2.0", "generator": "benches/cycles_scene.py"}, "scene": 0,
                     "scenes": [{"nodes": []}], "nodes": [], "meshes": [], "materials": [],
                     "accessors": [], "bufferViews": [], "buffers": []}

    def material(self, name, albedo, emission=None):
        m = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": [*albedo, 1.0],
                                                    "metallicFactor": 0.0, "roughnessFactor": 1.0}}
        if emission is not None:
            # emissiveFactor is at most 1: the rest goes in KHR_materials_emissive_strength.
            strength = max(emission)
            m["emissiveFactor"] = [e / strength for e in emission]
            m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}
            self.gltf.setdefault("extensionsUsed", ["KHR_materials_emissive_strength"])
        self.gltf["materials"].append(m)
        return len(self.gltf["materials"]) - 1

    def _accessor(self, array, kind, target):
        array = np.ascontiguousarray(array)
        while len(self.bin) % 4:
            self.bin.append(0)
        self.gltf["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": array.nbytes,
                                         "target": target})
        self.bin += array.tobytes()
        acc = {"bufferView": len(self.gltf["bufferViews"]) - 1, "count": len(array), "type": kind,
               "componentType": 5125 if array.dtype == np.uint32 else 5126}
        if kind == "VEC3" and target == 34962:
            acc["min"], acc["max"] = array.min(0).tolist(), array.max(0).tolist()
        self.gltf["accessors"].append(acc)
        return len(self.gltf["accessors"]) - 1

    def mesh(self, name, quads, material):
        """quads: (corner, u edge, v edge) each; the front faces along u × v."""
        pos, nrm, uv, idx = [], [], [], []
        for corner, u, v in quads:
            corner, u, v = (np.asarray(a, np.float32) for a in (corner, u, v))
            n = np.cross(u, v)
            base = len(pos)
            pos += [corner, corner + u, corner + u + v, corner + v]
            nrm += [n / np.linalg.norm(n)] * 4
            uv += [[0, 0], [np.linalg.norm(u), 0], [np.linalg.norm(u), np.linalg.norm(v)], [0, np.linalg.norm(v)]]
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
        attributes = {"POSITION": self._accessor(np.array(pos, np.float32), "VEC3", 34962),
                      "NORMAL": self._accessor(np.array(nrm, np.float32), "VEC3", 34962),
                      "TEXCOORD_0": self._accessor(np.array(uv, np.float32), "VEC2", 34962)}
        self._object(name, attributes, np.array(idx, np.uint32), material)

    def triangles(self, name, positions, indices, material):
        """One primitive from a (n, 3) position array and a flat index array."""
        attributes = {"POSITION": self._accessor(np.asarray(positions, np.float32), "VEC3", 34962)}
        self._object(name, attributes, np.asarray(indices, np.uint32), material)

    def _object(self, name, attributes, indices, material):
        """A mesh of one primitive and the node that places it in the scene."""
        indices = self._accessor(indices, "SCALAR", 34963)
        self.gltf["meshes"].append({"name": name, "primitives": [
            {"attributes": attributes, "indices": indices, "material": material}]})
        self.gltf["nodes"].append({"name": name, "mesh": len(self.gltf["meshes"]) - 1})
        self.gltf["scenes"][0]["nodes"].append(len(self.gltf["nodes"]) - 1)

    def write(self, path):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.gltf["buffers"] = [{"byteLength": len(self.bin)}]
        text = json.dumps(self.gltf).encode()
        text += b" " * (-len(text) % 4)
        with open(path, "wb") as f:
            f.write(struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(self.bin)))
            f.write(struct.pack("<II", len(text), 0x4E4F534A) + text)
            f.write(struct.pack("<II", len(self.bin), 0x004E4942) + bytes(self.bin))


def wall_with_hole(corner, u, v, hole):
    """The quads of the face corner + s·u + t·v, s, t in [0, 1], less the
    rectangle hole = (s0, s1, t0, t1)."""
    corner, u, v = (np.asarray(a, float) for a in (corner, u, v))
    s0, s1, t0, t1 = hole
    return [(corner, u * s0, v), (corner + u * s1, u * (1 - s1), v),
            (corner + u * s0, u * (s1 - s0), v * t0), (corner + u * s0 + v * t1, u * (s1 - s0), v * (1 - t1))]


def room_faces(w, h, d):
    """The six inward faces of the box [-w/2, w/2] × [0, h] × [-d/2, d/2] as
    (corner, u, v) keyed by the side they are on."""
    x, z = w / 2, d / 2
    return {
        "floor": ((-x, 0, -z), (0, 0, d), (w, 0, 0)),
        "ceiling": ((-x, h, -z), (w, 0, 0), (0, 0, d)),
        "-x": ((-x, 0, -z), (0, h, 0), (0, 0, d)),
        "+x": ((x, 0, -z), (0, 0, d), (0, h, 0)),
        "-z": ((-x, 0, -z), (w, 0, 0), (0, h, 0)),
        "+z": ((-x, 0, z), (0, h, 0), (w, 0, 0)),
    }


def box(centre, size):
    """The outward faces of an axis-aligned box standing on the floor, less
    the bottom one (it would lie in the floor's plane)."""
    c, s = np.asarray(centre, float), np.asarray(size, float) / 2
    ex, ey, ez = np.diag(s * 2)
    lo = c - s
    return [(lo + ey, ez, ex), (lo, ez, ey), (lo + ex, ey, ez), (lo, ey, ex), (lo + ez, ex, ey)]


def window_room(path):
    """4 × 2.8 × 4 m room, a 2 × 1.4 m window in the +X wall, red -Z and
    green -X walls, a white box on the floor."""
    g = Glb()
    white, red, green = g.material("white", (0.8, 0.8, 0.8)), g.material("red", (0.8, 0.15, 0.1)), \
        g.material("green", (0.15, 0.7, 0.15))
    faces = room_faces(4.0, 2.8, 4.0)
    g.mesh("floor", [faces["floor"]], white)
    g.mesh("ceiling", [faces["ceiling"]], white)
    g.mesh("red wall", [faces["-z"]], red)
    g.mesh("green wall", [faces["-x"]], green)
    g.mesh("back wall", [faces["+z"]], white)
    g.mesh("window wall", wall_with_hole(*faces["+x"], (0.25, 0.75, 0.3, 0.8)), white)
    g.mesh("box", box((-0.6, 0.35, -0.7), (0.7, 0.7, 0.7)), white)
    g.write(path)


def emitter_room(path):
    """5 × 3 × 4 m closed room lit only by a 1.2 × 1.2 m ceiling panel
    (radiance 10) set flush into a hole in the ceiling; a blue -Z wall, a
    white box and a tall yellow box."""
    g = Glb()
    white, blue, yellow = g.material("white", (0.8, 0.8, 0.8)), g.material("blue", (0.1, 0.2, 0.75)), \
        g.material("yellow", (0.8, 0.7, 0.2))
    light = g.material("panel", (0.8, 0.8, 0.8), emission=(10.0, 10.0, 10.0))
    w, h, d = 5.0, 3.0, 4.0
    faces = room_faces(w, h, d)
    hole = ((w - 1.2) / 2 / w, (w + 1.2) / 2 / w, (d - 1.2) / 2 / d, (d + 1.2) / 2 / d)
    g.mesh("floor", [faces["floor"]], white)
    g.mesh("ceiling", wall_with_hole(*faces["ceiling"], hole), white)
    g.mesh("panel", [((-0.6, h, -0.6), (1.2, 0, 0), (0, 0, 1.2))], light)
    g.mesh("blue wall", [faces["-z"]], blue)
    g.mesh("walls", [faces["-x"], faces["+x"], faces["+z"]], white)
    g.mesh("box", box((1.2, 0.4, 0.5), (0.8, 0.8, 0.8)), white)
    g.mesh("tall box", box((-1.3, 0.9, -0.8), (0.6, 1.8, 0.6)), yellow)
    g.write(path)


def rolling_terrain(path, cells=300):
    """A 20 × 20 m heightfield of cells × cells quads (180,000 triangles at
    300), rolling ±0.5 m with wavelengths of about 9 and 10 m: a surface that
    crosses the plane of almost every point on it many times."""
    g = Glb()
    ground = g.material("ground", (0.5, 0.45, 0.35))
    t = np.linspace(-10.0, 10.0, cells + 1)
    x, z = np.meshgrid(t, t, indexing="ij")
    y = 0.5 * np.sin(0.7 * x) * np.cos(0.6 * z)
    positions = np.stack([x, y, z], -1).reshape(-1, 3)
    a = (np.arange(cells)[:, None] * (cells + 1) + np.arange(cells)[None, :]).ravel()
    b, c = a + 1, a + cells + 1
    indices = np.stack([a, b, c, b, c + 1, c], -1).ravel()
    g.triangles("terrain", positions, indices, ground)
    g.write(path)
