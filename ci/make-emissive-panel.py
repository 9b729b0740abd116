#!/usr/bin/env python3
"""Writes scenes/emissive-panel.gltf, the bench's emissive-textured screen: a room lit only by a large wall screen
(48 x 27 quads under one emissive texture) showing a mostly black picture with a bright logo and a thin bright
ticker. Light selection that knows each triangle's power by the texels it covers samples the logo and the ticker;
by the texture's average, nineteen picks in twenty would land on black.

Usage: ci/make-emissive-panel.py (no arguments; deterministic).
"""
import base64
import json
import math
import os
import struct
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "scenes", "emissive-panel.gltf")

# The picture: 192 x 108 sRGB texels, near black but for a ring-and-bar logo and a ticker along the bottom.
W, H = 192, 108
rows = []
for y in range(H):
    row = []
    for x in range(W):
        r = g = b = 3
        d = math.hypot(x - 48, y - 40)
        if 14 <= d <= 22 or (70 <= x <= 130 and 34 <= y <= 46):
            r, g, b = 255, 230, 180
        elif 96 <= y <= 100 and 8 <= x <= 184:
            r, g, b = 120, 200, 255
        row.append((r, g, b))
    rows.append(row)


def png(rows):
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", len(rows[0]), len(rows), 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


LAMBERT = {"KHR_materials_specular": {"specularFactor": 0.0}}


def lambert(name, colour):
    return {"name": name, "extensions": dict(LAMBERT),
            "pbrMetallicRoughness": {"baseColorFactor": colour + [1], "metallicFactor": 0, "roughnessFactor": 1}}


materials = [lambert("floor", [0.6, 0.6, 0.6]), lambert("wall", [0.5, 0.5, 0.55]), lambert("box", [0.6, 0.4, 0.3])]
screen = lambert("screen", [0.0, 0.0, 0.0])
screen["emissiveFactor"] = [1, 1, 1]
screen["emissiveTexture"] = {"index": 0}
screen["extensions"]["KHR_materials_emissive_strength"] = {"emissiveStrength": 20}
materials.append(screen)

prims = {}  # material -> (positions, uvs or None, indices)


def quad(corners, material, uvs=None):
    """Corners counter-clockwise seen from the side the quad faces."""
    pos, tex, idx = prims.setdefault(material, ([], [] if uvs else None, []))
    base = len(pos)
    pos.extend(corners)
    if uvs:
        tex.extend(uvs)
    idx.extend([base, base + 1, base + 2, base, base + 2, base + 3])


def box(lo, hi, material):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    quad([(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)], material)  # +y
    quad([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], material)  # +z
    quad([(x1, y0, z0), (x0, y0, z0), (x0, y1, z0), (x1, y1, z0)], material)  # -z
    quad([(x1, y0, z1), (x1, y0, z0), (x1, y1, z0), (x1, y1, z1)], material)  # +x
    quad([(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)], material)  # -x


quad([(-5, 0, -3), (-5, 0, 6), (5, 0, 6), (5, 0, -3)], 0)  # floor, +y
quad([(-5, 0, -3), (5, 0, -3), (5, 5, -3), (-5, 5, -3)], 1)  # back wall, +z
quad([(-5, 0, 6), (-5, 0, -3), (-5, 5, -3), (-5, 5, 6)], 1)  # left wall, +x
box((-2.0, 0, -0.5), (-1.0, 0.8, 0.5), 2)
box((0.8, 0, 0.8), (1.6, 1.4, 1.6), 2)
# The screen, 4.8 x 2.7 m, 5 cm in front of the back wall, facing +z; uv (0, 0) at its top left as glTF has it.
NX, NY, X0, Y1 = 48, 27, -2.4, 3.8
for j in range(NY):
    for i in range(NX):
        xa, xb = X0 + 4.8 * i / NX, X0 + 4.8 * (i + 1) / NX
        ya, yb = Y1 - 2.7 * (j + 1) / NY, Y1 - 2.7 * j / NY
        ua, ub = i / NX, (i + 1) / NX
        va, vb = (j + 1) / NY, j / NY
        quad([(xa, ya, -2.95), (xb, ya, -2.95), (xb, yb, -2.95), (xa, yb, -2.95)], 3,
             [(ua, va), (ub, va), (ub, vb), (ua, vb)])

data, views, accessors, meshes = b"", [], [], []


def view(blob, target=None):
    global data
    views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(blob), **({"target": target} if target else {})})
    data += blob
    while len(data) % 4:
        data += b"\x00"
    return len(views) - 1


for m, (pos, tex, idx) in prims.items():
    attrs = {}
    accessors.append({"bufferView": view(b"".join(struct.pack("<3f", *p) for p in pos), 34962), "componentType": 5126,
                      "count": len(pos), "type": "VEC3", "min": [min(p[k] for p in pos) for k in range(3)],
                      "max": [max(p[k] for p in pos) for k in range(3)]})
    attrs["POSITION"] = len(accessors) - 1
    if tex:
        accessors.append({"bufferView": view(b"".join(struct.pack("<2f", *t) for t in tex), 34962),
                          "componentType": 5126, "count": len(tex), "type": "VEC2"})
        attrs["TEXCOORD_0"] = len(accessors) - 1
    accessors.append({"bufferView": view(b"".join(struct.pack("<I", i) for i in idx), 34963), "componentType": 5125,
                      "count": len(idx), "type": "SCALAR"})
    meshes.append({"name": materials[m]["name"],
                   "primitives": [{"attributes": attrs, "indices": len(accessors) - 1, "material": m}]})
image_view = view(png(rows))
nodes = [{"mesh": k} for k in range(len(meshes))]
# From the front right, looking at the screen and the boxes, a little down.
yaw, pitch = math.atan2(2.2, 8.5), -math.atan2(0.5, 8.8)  # towards (0, 1.7, -3)
cy, sy, cp, sp = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(pitch / 2), math.sin(pitch / 2)
nodes.append({"camera": 0, "translation": [2.2, 2.2, 5.5], "rotation": [cy * sp, sy * cp, -sy * sp, cy * cp]})
doc = {
    "asset": {"version": "2.0", "generator": "pathwave ci/make-emissive-panel.py"},
    "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
    "scene": 0,
    "scenes": [{"nodes": list(range(len(nodes)))}],
    "nodes": nodes,
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.9, "aspectRatio": 1.5, "znear": 0.05}}],
    "meshes": meshes,
    "materials": materials,
    "images": [{"bufferView": image_view, "mimeType": "image/png"}],
    # Linear filtering, clamped at the edges: what the bench's Mitsuba translation reads the same way.
    "samplers": [{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}],
    "textures": [{"source": 0, "sampler": 0}],
    "accessors": accessors,
    "bufferViews": views,
    "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
}
with open(OUT, "w") as f:
    json.dump(doc, f, indent=1)
print(f"wrote {OUT}: {NX * NY * 2} screen triangles under a {W}x{H} emissive texture")
