#!/usr/bin/env python3
"""Writes scenes/city-block.gltf, the bench's city at night: two streets crossing between blocks of buildings whose
facades hold thousands of lit windows (each window a quad slightly proud of its wall, of one of eight emissive
materials whose strengths span two decades, many windows dark), seen from the pavement. Most windows face away from
any given point of the street or are far down it: selection by power spreads next-event samples over all of them,
selection by importance at the shading point picks the windows across the street.

Usage: ci/make-city-block.py (no arguments; deterministic).
"""
import base64
import json
import os
import random
import struct

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "scenes", "city-block.gltf")

# Lambertian throughout (KHR_materials_specular 0), so the scene translates to Mitsuba 3 for the bench.
LAMBERT = {"KHR_materials_specular": {"specularFactor": 0.0}}


def lambert(name, colour, emission=None, strength=None):
    m = {"name": name, "extensions": dict(LAMBERT),
         "pbrMetallicRoughness": {"baseColorFactor": colour + [1], "metallicFactor": 0, "roughnessFactor": 1}}
    if emission:
        m["emissiveFactor"] = emission
        m["extensions"]["KHR_materials_emissive_strength"] = {"emissiveStrength": strength}
    return m


materials = [lambert("road", [0.25, 0.25, 0.27]), lambert("pavement", [0.5, 0.48, 0.45]),
             lambert("wall", [0.55, 0.5, 0.45]), lambert("dark window", [0.05, 0.05, 0.06])]
rng = random.Random(20261204)
WINDOWS = []
for k in range(8):
    strength = 10 ** (-1 + 2 * k / 7)  # 0.1 .. 10 W/(m^2 sr)
    warm = [1.0, 0.7 + 0.25 * rng.random(), 0.4 + 0.4 * rng.random()]
    WINDOWS.append(len(materials))
    materials.append(lambert(f"window {k}", [0, 0, 0], warm, round(strength, 3)))

quads = {m: [] for m in range(len(materials))}


def quad(corners, material):
    """Corners counter-clockwise seen from the side the quad faces."""
    quads[material].append(corners)


def facade(origin, along, width, height, floors, columns):
    """A wall from origin, `along` its unit direction in the ground plane, facing along x up (its outward normal
    is along x (0, 1, 0)), with a grid of windows a few centimetres in front of it."""
    ax, az = along
    nx, nz = -az, ax  # outward: along x up
    ox, oz = origin

    def at(s, y, out=0.0):
        return (ox + ax * s + nx * out, y, oz + az * s + nz * out)

    quad([at(0, 0), at(width, 0), at(width, height), at(0, height)], 2)
    floor_h = height / floors
    col_w = width / columns
    for f in range(floors):
        for c in range(columns):
            s0, y0 = c * col_w + 0.25 * col_w, f * floor_h + 0.3 * floor_h
            s1, y1 = s0 + 0.5 * col_w, y0 + 0.45 * floor_h
            lit = rng.random() < 0.7
            m = rng.choice(WINDOWS) if lit else 3
            quad([at(s0, y0, 0.03), at(s1, y0, 0.03), at(s1, y1, 0.03), at(s0, y1, 0.03)], m)


def building(x0, z0, x1, z1, height):
    floors = max(2, int(height / 3.2))
    # Counter-clockwise around the footprint seen from above, so every facade faces out.
    corners = [(x0, z1), (x1, z1), (x1, z0), (x0, z0)]
    for k in range(4):
        (ax, az), (bx, bz) = corners[k], corners[(k + 1) % 4]
        length = abs(bx - ax) + abs(bz - az)
        along = ((bx - ax) / length, (bz - az) / length)
        facade((ax, az), along, length, height, floors, max(2, int(length / 2.4)))
    quad([(x0, height, z0), (x0, height, z1), (x1, height, z1), (x1, height, z0)], 2)  # roof, +y


# Streets along x and z through the origin, 12 m wide with 3 m pavements; blocks of buildings in the quadrants.
R = 120.0
quad([(-R, 0, -R), (-R, 0, R), (R, 0, R), (R, 0, -R)], 0)
for sx in (-1, 1):
    for sz in (-1, 1):
        # This quadrant's pavement, facing up.
        (x0, x1), (z0, z1) = sorted((sx * 6, sx * 60)), sorted((sz * 6, sz * 60))
        quad([(x0, 0.01, z0), (x0, 0.01, z1), (x1, 0.01, z1), (x1, 0.01, z0)], 1)
        # A corner building, then a row along each street behind it: no two buildings overlap or share a wall
        # (coplanar walls would leave which window a ray meets to the renderer, and the bench compares renderers).
        (x0, x1), (z0, z1) = sorted((sx * 9.0, sx * 23.0)), sorted((sz * 9.0, sz * 23.0))
        building(x0, z0, x1, z1, 12 + 24 * rng.random())
        for street in (0, 1):
            along = 25.0
            while along < 56:
                w = 8 + 6 * rng.random()
                d = 10 + 4 * rng.random()
                a0, a1 = along, min(along + w, 58)
                # Along the x street (street 0) the run is in x and the depth in z; along the z street, the reverse.
                (u0, u1), (v0, v1) = (a0, a1), (9.0, 9.0 + d)
                if street == 1:
                    (u0, u1), (v0, v1) = (v0, v1), (u0, u1)
                x0, x1 = sorted((sx * u0, sx * u1))
                z0, z1 = sorted((sz * v0, sz * v1))
                building(x0, z0, x1, z1, 10 + 30 * rng.random())
                along = a1 + 1.0

positions, meshes, accessors, views, data = [], [], [], [], b""
for m, qs in quads.items():
    if not qs:
        continue
    verts = [c for q in qs for c in q]
    idx = [i for k in range(len(qs)) for i in (4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 0, 4 * k + 2, 4 * k + 3)]
    pos = b"".join(struct.pack("<3f", *p) for p in verts)
    ind = b"".join(struct.pack("<I", i) for i in idx)
    views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(pos), "target": 34962})
    data += pos
    views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(ind), "target": 34963})
    data += ind
    accessors.append({"bufferView": len(views) - 2, "componentType": 5126, "count": len(verts), "type": "VEC3",
                      "min": [min(p[k] for p in verts) for k in range(3)],
                      "max": [max(p[k] for p in verts) for k in range(3)]})
    accessors.append({"bufferView": len(views) - 1, "componentType": 5125, "count": len(idx), "type": "SCALAR"})
    meshes.append({"name": materials[m]["name"],
                   "primitives": [{"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1,
                                   "material": m}]})
nodes = [{"mesh": k} for k in range(len(meshes))]
# On the pavement at the crossing, eye height, looking down the street along -z, a little up.
nodes.append({"camera": 0, "translation": [3.0, 1.7, 14.0], "rotation": [0.0871557, 0, 0, 0.9961947]})
doc = {
    "asset": {"version": "2.0", "generator": "pathwave ci/make-city-block.py"},
    "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
    "scene": 0,
    "scenes": [{"nodes": list(range(len(nodes)))}],
    "nodes": nodes,
    "cameras": [{"type": "perspective", "perspective": {"yfov": 1.0, "aspectRatio": 1.5, "znear": 0.05}}],
    "meshes": meshes,
    "materials": materials,
    "accessors": accessors,
    "bufferViews": views,
    "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
}
with open(OUT, "w") as f:
    json.dump(doc, f, indent=1)
lit = sum(len(quads[m]) for m in WINDOWS)
print(f"wrote {OUT}: {sum(len(q) for q in quads.values())} quads, {lit} lit windows")
