# Renders a small glTF scene with Mitsuba 3 as the independent reference of tests/media.rs: read here from the glTF
# JSON and the extensions' texts (not through pathwave), so a misreading in pathwave's loader or its translation for
# the bench does not carry over. Writes per-pixel batch statistics for pathwave's statistical diff.
#
# Understood: nodes (TRS or matrix, nested), one perspective camera, triangle meshes with POSITION and optional
# NORMAL, Lambertian materials (KHR_materials_specular 0, metallic 0), emission (with
# KHR_materials_emissive_strength), and dielectrics (KHR_materials_transmission 1, KHR_materials_ior, roughness) whose
# KHR_materials_volume interior attenuates and, with KHR_materials_scatter, scatters. Anything else is refused.
#
# Usage: render_gltf.py SCENE.gltf OUTDIR --width W --height H --spp S --batches K
# OUTDIR gets mean.f32 and var.f32 (H x W x RGB little-endian float32: per pixel the mean over K independent
# renders of S/K samples each, and the sample variance of those K batch means) and info.json.
import argparse
import base64
import json
import math
import os
import time

import numpy as np

COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}


class Gltf:
    def __init__(self, path):
        self.dir = os.path.dirname(os.path.abspath(path))
        with open(path) as f:
            self.json = json.load(f)
        self.buffers = [self.buffer(b) for b in self.json.get("buffers", [])]

    def buffer(self, b):
        uri = b["uri"]
        if uri.startswith("data:"):
            return base64.b64decode(uri.split(",", 1)[1])
        with open(os.path.join(self.dir, uri), "rb") as f:
            return f.read()

    def accessor(self, i):
        a = self.json["accessors"][i]
        n, comps, dtype = a["count"], COMPONENTS[a["type"]], DTYPES[a["componentType"]]
        view = self.json["bufferViews"][a["bufferView"]]
        data = self.buffers[view["buffer"]]
        start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        size = np.dtype(dtype).itemsize * comps
        stride = view.get("byteStride", size)
        rows = [np.frombuffer(data, dtype, comps, start + k * stride) for k in range(n)]
        return np.array(rows, dtype=np.float64 if dtype == np.float32 else np.int64).reshape(n, comps)


def node_matrix(node):
    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major in the file
    t = np.eye(4)
    t[:3, 3] = node.get("translation", [0, 0, 0])
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    r = np.eye(4)
    r[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    s = np.diag(list(node.get("scale", [1, 1, 1])) + [1])
    return t @ r @ s


def world_nodes(g):
    """(node, world matrix) for every node under the default scene's roots."""
    nodes = g.json["nodes"]
    scene = g.json["scenes"][g.json.get("scene", 0)]
    stack = [(i, np.eye(4)) for i in scene["nodes"]]
    while stack:
        i, parent = stack.pop()
        m = parent @ node_matrix(nodes[i])
        yield nodes[i], m
        stack.extend((c, m) for c in nodes[i].get("children", []))


def single_scatter_albedo(rho_ms, g):
    """KHR_materials_scatter's mapping from the multi-scatter albedo to the single-scatter one (its README, after
    Kulla and Conty 2017)."""
    s = 4.09712 + 4.20863 * rho_ms - math.sqrt(9.59217 + 41.6808 * rho_ms + 17.7126 * rho_ms**2)
    return (1 - s * s) / (1.0 - g * s * s)


def bsdf_and_interior(mat):
    """The Mitsuba BSDF of a glTF material, and the medium inside it (None for none)."""
    ext = mat.get("extensions", {})
    pbr = mat.get("pbrMetallicRoughness", {})
    base = pbr.get("baseColorFactor", [1, 1, 1, 1])[:3]
    metallic = pbr.get("metallicFactor", 1.0)
    roughness = pbr.get("roughnessFactor", 1.0)
    transmission = ext.get("KHR_materials_transmission", {}).get("transmissionFactor", 0.0)
    specular = ext.get("KHR_materials_specular", {}).get("specularFactor", 1.0)
    known = {"KHR_materials_transmission", "KHR_materials_specular", "KHR_materials_emissive_strength",
             "KHR_materials_ior", "KHR_materials_volume", "KHR_materials_scatter"}
    if set(ext) - known or metallic != 0.0 or any(k in mat for k in ("normalTexture", "occlusionTexture")):
        raise SystemExit(f"material {mat.get('name')!r}: not understood by this script")
    if transmission == 0.0:
        if specular != 0.0:
            raise SystemExit(f"material {mat.get('name')!r}: only Lambertian (specularFactor 0) opaque materials")
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": base}}, None
    if transmission != 1.0 or specular != 1.0 or base != [1, 1, 1]:
        raise SystemExit(f"material {mat.get('name')!r}: only clear dielectrics (transmission 1, white) translate")
    ior = ext.get("KHR_materials_ior", {}).get("ior", 1.5)
    # ext_ior 1: the glTF world is vacuum-like (Mitsuba's default outside is air, 1.000277).
    if ior == 1.0:
        # An interface between equal indices is no interface: Mitsuba's null BSDF, which shadow rays cross.
        bsdf = {"type": "null"}
    elif roughness == 0.0:
        bsdf = {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0}
    else:
        bsdf = {"type": "roughdielectric", "distribution": "ggx", "alpha": roughness**2, "int_ior": ior,
                "ext_ior": 1.0}
    volume = ext.get("KHR_materials_volume")
    if volume is None or volume.get("thicknessFactor", 0.0) == 0.0:
        raise SystemExit(f"material {mat.get('name')!r}: thin-walled transmission is not translated")
    # KHR_materials_volume: sigma_t = -ln(attenuationColor) / attenuationDistance (distance infinite by default).
    color = np.array(volume.get("attenuationColor", [1, 1, 1]), dtype=np.float64)
    distance = volume.get("attenuationDistance", math.inf)
    sigma_t = -np.log(color) / distance
    scatter = ext.get("KHR_materials_scatter", {})
    strength = scatter.get("scatterStrengthFactor", 0.0)
    g = scatter.get("scatterAnisotropy", 0.0)
    # scatterStrength scales the multi-scatter albedo (volumetric mode).
    rho_ms = strength * np.array(scatter.get("multiscatterColorFactor", [1, 1, 1]), dtype=np.float64)
    albedo = [min(1.0, max(0.0, single_scatter_albedo(r, g))) if r > 0 else 0.0 for r in rho_ms]
    scale = float(sigma_t.max())
    if scale == 0.0:
        return bsdf, None
    # Mitsuba's RGB values are reflectances in [0, 1]: sigma_t travels normalised, its size in `scale`.
    interior = {
        "type": "homogeneous",
        "sigma_t": {"type": "rgb", "value": (sigma_t / scale).tolist()},
        "scale": scale,
        "albedo": {"type": "rgb", "value": albedo},
        "phase": {"type": "hg", "g": g},
        # Inside a dielectric every shadow ray is blocked: Mitsuba's documentation says to trace none.
        "sample_emitters": bsdf["type"] == "null",
    }
    return bsdf, interior


def write_ply(path, positions, normals):
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(positions)}",
              "property float x", "property float y", "property float z"]
    if normals is not None:
        header += ["property float nx", "property float ny", "property float nz"]
    header += [f"element face {len(positions) // 3}", "property list uchar int vertex_indices", "end_header", ""]
    verts = positions if normals is None else np.hstack([positions, normals])
    faces = np.zeros(len(positions) // 3, dtype=[("n", "u1"), ("i", "<i4", 3)])
    faces["n"] = 3
    faces["i"] = np.arange(len(positions), dtype=np.int32).reshape(-1, 3)
    with open(path, "wb") as f:
        f.write("\n".join(header).encode())
        f.write(verts.astype("<f4").tobytes())
        f.write(faces.tobytes())


def scene_dict(g, width, height, workdir, integrator):
    scene = {"type": "scene"}
    materials = g.json.get("materials", [])
    has_media = False
    camera = None
    for k, (node, m) in enumerate(world_nodes(g)):
        if "camera" in node:
            cam = g.json["cameras"][node["camera"]]
            if cam["type"] != "perspective":
                raise SystemExit("only perspective cameras")
            # The camera looks down its node's -z with +y up.
            origin = m[:3, 3]
            camera = {"origin": origin.tolist(), "target": (origin - m[:3, 2]).tolist(), "up": m[:3, 1].tolist(),
                      "yfov": math.degrees(cam["perspective"]["yfov"])}
        if "mesh" not in node:
            continue
        normal_matrix = np.linalg.inv(m[:3, :3]).T
        for p, prim in enumerate(g.json["meshes"][node["mesh"]]["primitives"]):
            if prim.get("mode", 4) != 4:
                raise SystemExit("only triangle lists")
            pos = g.accessor(prim["attributes"]["POSITION"])
            idx = g.accessor(prim["indices"]).ravel() if "indices" in prim else np.arange(len(pos))
            world = (np.hstack([pos, np.ones((len(pos), 1))]) @ m.T)[:, :3][idx]
            normals = None
            if "NORMAL" in prim["attributes"]:
                n = g.accessor(prim["attributes"]["NORMAL"]) @ normal_matrix.T
                normals = (n / np.linalg.norm(n, axis=1, keepdims=True))[idx]
            mat = materials[prim["material"]] if "material" in prim else {}
            bsdf, interior = bsdf_and_interior(mat)
            ply = os.path.join(workdir, f"mesh{k}_{p}.ply")
            write_ply(ply, world, normals)
            # Without NORMAL, glTF asks for flat normals: Mitsuba's face normals.
            shape = {"type": "ply", "filename": ply, "face_normals": normals is None, "bsdf": bsdf}
            if mat.get("doubleSided", False) and bsdf["type"] == "diffuse":
                shape["bsdf"] = {"type": "twosided", "bsdf": bsdf}
            strength = mat.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1)
            emission = [strength * e for e in mat.get("emissiveFactor", [0, 0, 0])]
            if max(emission) > 0:
                # glTF emits from front faces only unless double-sided; Mitsuba's area light is one-sided as well.
                if mat.get("doubleSided", False):
                    raise SystemExit("double-sided emitters are not translated")
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": emission}}
            if interior is not None:
                shape["interior"] = interior
                has_media = True
            scene[f"mesh{k}_{p}"] = shape
    if camera is None:
        raise SystemExit("the scene has no camera")
    import mitsuba as mi

    scene["sensor"] = {
        "type": "perspective",
        "fov": camera["yfov"],
        "fov_axis": "y",
        "near_clip": 1e-3,
        "to_world": mi.ScalarTransform4f().look_at(origin=camera["origin"], target=camera["target"], up=camera["up"]),
        "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        "sampler": {"type": "independent"},
    }
    scene["integrator"] = {"type": integrator if has_media else "path", "max_depth": -1}
    return scene


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--width", type=int, required=True)
    ap.add_argument("--height", type=int, required=True)
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--batches", type=int, default=16)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    # volpathmis: Mitsuba's spectral MIS over channels (pathwave's approach), much less noisy in chromatic media.
    ap.add_argument("--integrator", default="volpath", choices=["volpath", "volpathmis"])
    args = ap.parse_args()
    import mitsuba as mi

    mi.set_variant(args.variant)
    os.makedirs(args.out, exist_ok=True)
    scene = mi.load_dict(scene_dict(Gltf(args.scene), args.width, args.height, args.out, args.integrator))
    per_batch = max(1, args.spp // args.batches)
    start = time.perf_counter()
    images = []
    for b in range(args.batches):
        img = np.asarray(mi.render(scene, spp=per_batch, seed=1000 + b), dtype=np.float64)[..., :3]
        images.append(img)
    images = np.stack(images)
    mean = images.mean(axis=0)
    var = images.var(axis=0, ddof=1)
    mean.astype("<f4").tofile(os.path.join(args.out, "mean.f32"))
    var.astype("<f4").tofile(os.path.join(args.out, "var.f32"))
    info = {"batches": args.batches, "spp_per_batch": per_batch, "seconds": time.perf_counter() - start,
            "variant": args.variant, "version": mi.__version__}
    with open(os.path.join(args.out, "info.json"), "w") as f:
        json.dump(info, f)
    print(json.dumps(info))


if __name__ == "__main__":
    main()
