#!/usr/bin/env python3
"""Writes scenes/lamp-grid.gltf, the many-lights scene of the light-selection tests and the bench: a floor with a few
boxes under a 16 x 16 grid of small down-facing lamps whose powers span three decades (log-uniform, fixed seed), and
four large, very bright panels far outside the view that hold most of the scene's power. Selection by power spends
most next-event samples on the far panels; selection by importance at the shading point picks the lamps overhead.

Usage: ci/make-lamp-grid.py (no arguments; deterministic).
"""
import base64
import json
import os
import random
import struct

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "scenes", "lamp-grid.gltf")

positions, indices, primitives = [], [], []


def quad(corners, material):
    """Two triangles over four corners given counter-clockwise as seen from the side they face."""
    base = len(positions)
    positions.extend(corners)
    first = len(indices)
    indices.extend([base, base + 1, base + 2, base, base + 2, base + 3])
    primitives.append((first, 6, material, base, 4))


def box(lo, hi, material):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    quad([(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)], material)  # top, +y
    quad([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], material)  # +z
    quad([(x1, y0, z0), (x0, y0, z0), (x0, y1, z0), (x1, y1, z0)], material)  # -z
    quad([(x1, y0, z1), (x1, y0, z0), (x1, y1, z0), (x1, y1, z1)], material)  # +x
    quad([(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)], material)  # -x


# Lambertian throughout (KHR_materials_specular 0), so the scene translates to Mitsuba 3 for the bench.
LAMBERT = {"KHR_materials_specular": {"specularFactor": 0.0}}
materials = [
    {"name": "floor", "extensions": LAMBERT,
     "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1], "metallicFactor": 0, "roughnessFactor": 1}},
    {"name": "box", "extensions": LAMBERT,
     "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.45, 0.3, 1], "metallicFactor": 0, "roughnessFactor": 1}},
]
quad([(-10, 0, -10), (-10, 0, 10), (10, 0, 10), (10, 0, -10)], 0)
box((-2.5, 0, -1.0), (-1.5, 1.2, 0.0), 1)
box((1.0, 0, 0.5), (2.2, 0.6, 1.5), 1)
box((-0.5, 0, -4.0), (0.5, 2.0, -3.0), 1)

rng = random.Random(20261204)
n, spacing, half = 16, 1.2, 0.1
for i in range(n):
    for j in range(n):
        x = (i - (n - 1) / 2) * spacing
        z = (j - (n - 1) / 2) * spacing
        y = 2.5 + 0.5 * rng.random()
        strength = 10 ** (-0.75 + 3 * rng.random())  # 0.18 .. 180 W/(m^2 sr): three decades
        hue = [1.0, 0.75 + 0.25 * rng.random(), 0.5 + 0.5 * rng.random()]
        materials.append({
            "name": f"lamp {i} {j}",
            "emissiveFactor": hue,
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": round(strength, 3)}, **LAMBERT},
            "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0, "roughnessFactor": 1},
        })
        # Facing down (-y).
        quad([(x - half, y, z - half), (x + half, y, z - half), (x + half, y, z + half), (x - half, y, z + half)],
             len(materials) - 1)

# Far panels, 40 m out and 12 m up, facing the scene's centre: most of the power, little of the light on the floor.
materials.append({
    "name": "far panel",
    "emissiveFactor": [1, 1, 1],
    "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 80}, **LAMBERT},
    "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0, "roughnessFactor": 1},
})
for angle in (0.4, 2.0, 3.6, 5.2):
    import math
    cx, cz = 40 * math.cos(angle), 40 * math.sin(angle)
    # Right-handed frame facing the centre: normal towards the origin.
    nx, nz = -math.cos(angle), -math.sin(angle)
    tx, tz = -nz, nx  # tangent in the ground plane
    c = []
    for (a, b) in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        c.append((cx + a * 1.5 * tx, 12 + b * 1.5, cz + a * 1.5 * tz))
    # Counter-clockwise seen from the front (the normal's side).
    e1 = [c[1][k] - c[0][k] for k in range(3)]
    e2 = [c[2][k] - c[0][k] for k in range(3)]
    cross = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    if cross[0] * nx + cross[2] * nz < 0:
        c.reverse()
    quad(c, len(materials) - 1)

pos_bytes = b"".join(struct.pack("<3f", *p) for p in positions)
idx_bytes = b"".join(struct.pack("<I", k) for k in indices)
data = pos_bytes + idx_bytes
accessors, meshes, nodes = [], [], []
views = [
    # Every primitive's positions are an accessor into this one view, which glTF then requires to state its stride.
    {"buffer": 0, "byteOffset": 0, "byteLength": len(pos_bytes), "byteStride": 12, "target": 34962},
    {"buffer": 0, "byteOffset": len(pos_bytes), "byteLength": len(idx_bytes), "target": 34963},
]
for (first, count, material, base, verts) in primitives:
    pts = positions[base:base + verts]
    accessors.append({
        "bufferView": 0, "byteOffset": 12 * base, "componentType": 5126, "count": verts, "type": "VEC3",
        "min": [min(p[k] for p in pts) for k in range(3)], "max": [max(p[k] for p in pts) for k in range(3)],
    })
    # Indices relative to this primitive's first vertex.
    rel = b"".join(struct.pack("<I", k - base) for k in indices[first:first + count])
    views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(rel), "target": 34963})
    data += rel
    accessors.append({"bufferView": len(views) - 1, "componentType": 5125, "count": count, "type": "SCALAR"})
    meshes.append({"primitives": [{"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1,
                                   "material": material}]})
    nodes.append({"mesh": len(meshes) - 1})

# The shared index view is not needed by any primitive: drop it and renumber.
views.pop(1)
for a in accessors:
    if "bufferView" in a and a["bufferView"] > 1:
        a["bufferView"] -= 1
data = pos_bytes + data[len(pos_bytes) + len(idx_bytes):]
for v in views[1:]:
    v["byteOffset"] -= len(idx_bytes)

nodes.append({"camera": 0, "translation": [0, 5.5, 9.5],
              "rotation": [-0.2588190451, 0, 0, 0.9659258263]})  # 30 degrees down
doc = {
    "asset": {"version": "2.0", "generator": "pathwave ci/make-lamp-grid.py"},
    "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
    "scene": 0,
    "scenes": [{"nodes": list(range(len(nodes)))}],
    "nodes": nodes,
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.9, "aspectRatio": 1.5, "znear": 0.05}}],
    "meshes": meshes,
    "materials": materials,
    "accessors": accessors,
    "bufferViews": views,
    "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
}
with open(OUT, "w") as f:
    json.dump(doc, f, indent=1)
print(f"wrote {OUT}: {len(primitives)} quads, {len(materials)} materials")
