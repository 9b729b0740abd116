#!/usr/bin/env python3
"""Regenerates tests/data/{webp,webp-lossy,ktx2-etc1s,ktx2-uastc}/textured.gltf: scenes/textured.gltf with every
image re-encoded by the reference encoders, for tests/compressed_textures.rs. Each folder also holds, in reference/,
what the reference decoder makes of each encoded image (PNG), which the test checks pathwave's decoders against.

  webp        cwebp -lossless, the textures naming only EXT_texture_webp images (extensionsRequired): the decoded
              texels are the PNG's exactly, so the render must be the original's bytes.
  webp-lossy  cwebp -q 80, the PNG kept as the core fallback source (EXT_texture_webp in extensionsUsed only).
  ktx2-*      Basis Universal ETC1S and UASTC (+ Zstandard) in KTX2 (KHR_texture_basisu, required).

Usage: ci/make-texture-scenes.py [--ktx2-encoder CMD] (CMD IN.png OUT.ktx2 MODE SRGB|LINEAR, see ci/basisu.sh).
"""
import base64
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SRC = os.path.join(ROOT, "scenes", "textured.gltf")


def load():
    with open(SRC) as f:
        doc = json.load(f)
    data = base64.b64decode(doc["buffers"][0]["uri"].split(",", 1)[1])
    return doc, data


def view_bytes(doc, data, v):
    view = doc["bufferViews"][v]
    start = view.get("byteOffset", 0)
    return data[start : start + view["byteLength"]]


def srgb_images(doc):
    """Images read as colour (sRGB): base colour and emissive; the others hold data."""
    srgb = set()
    for m in doc["materials"]:
        for slot in [m.get("pbrMetallicRoughness", {}).get("baseColorTexture"), m.get("emissiveTexture")]:
            if slot is not None:
                srgb.add(doc["textures"][slot["index"]]["source"])
    return srgb


def rewrite(doc, data, encoded, ext, mime, keep_fallback):
    """The scene with each image i's encoding `encoded[i]` appended to the buffer as a new image, and each texture
    naming it through `ext`; without `keep_fallback` the PNGs go and the extension is required."""
    doc = json.loads(json.dumps(doc))
    data = bytearray(data)
    first = len(doc["images"])
    for i in range(first):
        while len(data) % 4:
            data.append(0)
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(data), "byteLength": len(encoded[i])})
        data.extend(encoded[i])
        doc["images"].append({"bufferView": len(doc["bufferViews"]) - 1, "mimeType": mime})
    for t in doc["textures"]:
        t.setdefault("extensions", {})[ext] = {"source": first + t["source"]}
        if not keep_fallback:
            del t["source"]
    doc["extensionsUsed"] = sorted(set(doc.get("extensionsUsed", [])) | {ext})
    if not keep_fallback:
        # The PNGs are unreferenced now; their bytes stay in the buffer, which is harmless and keeps offsets simple.
        doc["extensionsRequired"] = sorted(set(doc.get("extensionsRequired", [])) | {ext})
    doc["buffers"][0] = {
        "byteLength": len(data),
        "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(data)).decode(),
    }
    doc["asset"]["generator"] = "pathwave ci/make-texture-scenes.py from scenes/textured.gltf"
    return doc


def write(name, doc, references):
    out = os.path.join(ROOT, "tests", "data", name)
    os.makedirs(os.path.join(out, "reference"), exist_ok=True)
    with open(os.path.join(out, "textured.gltf"), "w") as f:
        json.dump(doc, f, separators=(",", ":"))
    for i, png in enumerate(references):
        with open(os.path.join(out, "reference", f"{i}.png"), "wb") as f:
            f.write(png)
    print(f"wrote tests/data/{name}/textured.gltf and {len(references)} reference images")


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main():
    ktx2_encoder = None
    if "--ktx2-encoder" in sys.argv:
        ktx2_encoder = sys.argv[sys.argv.index("--ktx2-encoder") + 1]
    doc, data = load()
    srgb = srgb_images(doc)
    pngs = [view_bytes(doc, data, im["bufferView"]) for im in doc["images"]]
    with tempfile.TemporaryDirectory() as tmp:
        for i, png in enumerate(pngs):
            with open(os.path.join(tmp, f"{i}.png"), "wb") as f:
                f.write(png)

        def encode(tag, make, decode):
            encoded, references = [], []
            for i in range(len(pngs)):
                src, enc, ref = (os.path.join(tmp, f"{i}{s}") for s in (".png", f".{tag}", f".{tag}.png"))
                make(src, enc, i)
                decode(enc, ref)
                encoded.append(open(enc, "rb").read())
                references.append(open(ref, "rb").read())
            return encoded, references

        # -exact keeps the RGB under transparent texels, which the perforated screen's alpha test does not hide.
        dwebp = lambda enc, ref: run(["dwebp", enc, "-o", ref])
        lossless, refs = encode("lossless.webp", lambda s, e, i: run(["cwebp", "-lossless", "-exact", s, "-o", e]), dwebp)
        write("webp", rewrite(doc, data, lossless, "EXT_texture_webp", "image/webp", False), refs)
        lossy, refs = encode("lossy.webp", lambda s, e, i: run(["cwebp", "-q", "80", "-exact", s, "-o", e]), dwebp)
        write("webp-lossy", rewrite(doc, data, lossy, "EXT_texture_webp", "image/webp", True), refs)
        if ktx2_encoder:
            for mode in ["etc1s", "uastc"]:
                make = lambda s, e, i: run(
                    [ktx2_encoder, "encode", s, e, mode, "srgb" if i in srgb else "linear"]
                )
                unpack = lambda e, r: run([ktx2_encoder, "decode", e, r])
                encoded, refs = encode(f"{mode}.ktx2", make, unpack)
                write(f"ktx2-{mode}", rewrite(doc, data, encoded, "KHR_texture_basisu", "image/ktx2", False), refs)


main()
