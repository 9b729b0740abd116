# pathwave bench's other renderers: Mitsuba 3 (llvm_ad_rgb, llvm_ad_spectral) and Embree (embreex), driven over stdin/stdout.
# One JSON request per line in, one JSON reply per line out; arrays travel as raw little-endian files so the
# timings measure rendering and tracing, not serialisation. Written for the bench, run by it; not a public tool.
import json
import os
import sys
import threading
import time

import numpy as np

# Replies go to the original stdout; anything the libraries print there (Mitsuba logs to it) goes to stderr.
REPLIES = os.fdopen(os.dup(1), "w")
os.dup2(2, 1)


def reply(**kw):
    REPLIES.write(json.dumps(kw) + "\n")
    REPLIES.flush()


class Embree:
    def load(self, req):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        tris = np.fromfile(req["triangles"], dtype=np.float32).reshape(-1, 3, 3)
        start = time.perf_counter()
        self.scene = rtcs.EmbreeScene()
        self.mesh = TriangleMesh(self.scene, tris)
        # embreex commits (builds the BVH) on the first query: make that happen here, outside the timings.
        self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
        return {"build_s": time.perf_counter() - start, "triangles": int(tris.shape[0])}

    def trace(self, req):
        rays = np.fromfile(req["rays"], dtype=np.float32).reshape(-1, 2, 3)
        threads = int(req.get("threads") or os.cpu_count() or 1)
        # Contiguous per-thread slices; embreex releases the GIL inside its loop over rtcIntersect1.
        parts = np.array_split(np.arange(rays.shape[0]), threads)
        origins = [np.ascontiguousarray(rays[p, 0]) for p in parts]
        dirs = [np.ascontiguousarray(rays[p, 1]) for p in parts]
        hits = [None] * threads

        def work(k):
            hits[k] = self.scene.run(origins[k], dirs[k])

        workers = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
        start = time.perf_counter()
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        seconds = time.perf_counter() - start
        if req.get("hits"):
            # Untimed: distances (inf for a miss), so the bench can check both tracers saw the same scene.
            out = self.scene.run(rays[:, 0].copy(), rays[:, 1].copy(), output=1)
            t = np.where(out["primID"] >= 0, out["tfar"], np.inf).astype(np.float32)
            t.tofile(req["hits"])
        return {"seconds": seconds, "threads": threads}


class Mitsuba:
    def load(self, req):
        import mitsuba as mi

        # llvm_ad_spectral for pathwave --spectral: the same scene, with RGB inputs upsampled and the emitters times
        # D65, as pathwave does.
        mi.set_variant(req.get("variant", "llvm_ad_rgb"))
        self.mi = mi
        desc = json.load(open(req["scene"]))
        cam = desc["camera"]
        media = any((m.get("dielectric") or {}).get("interior") for m in desc["meshes"])
        scene = {
            "type": "scene",
            # With media, volpathmis: volpath weights a chromatic medium's free flights by per-channel ratios with a
            # heavy tail, and its mean converges from below (tests/media.rs measured 2 % low in red at 16384 spp), so
            # it would make a poor reference and a poor rival; volpathmis's spectral MIS is pathwave's approach.
            "integrator": {"type": "volpathmis" if media else "path", "max_depth": -1},
            "sensor": {
                "type": "perspective",
                "fov": cam["yfov_deg"],
                "fov_axis": "y",
                "near_clip": 1e-3,
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=cam["origin"], target=cam["target"], up=cam["up"]
                ),
                "film": {
                    "type": "hdrfilm",
                    "width": cam["width"],
                    "height": cam["height"],
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
            },
        }
        for k, m in enumerate(desc["meshes"]):
            shape = {
                "type": "ply",
                "filename": m["ply"],
                # Shading normals when pathwave has them (the PLY then carries them), else the faces'.
                "face_normals": not m.get("smooth", False),
            }
            if m.get("dielectric"):
                d = m["dielectric"]
                # Outside is vacuum, as in glTF (Mitsuba's default ext_ior is air's 1.000277). pathwave treats
                # alpha below 1e-4 as a smooth interface.
                if d["alpha"] < 1e-4:
                    shape["bsdf"] = {"type": "dielectric", "int_ior": d["ior"], "ext_ior": 1.0}
                else:
                    shape["bsdf"] = {"type": "roughdielectric", "distribution": "ggx", "alpha": d["alpha"],
                                     "int_ior": d["ior"], "ext_ior": 1.0}
                if d.get("interior"):
                    shape["interior"] = homogeneous(d["interior"])
            else:
                shape["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": m["reflectance"]}}
            if m.get("radiance_texture"):
                # Linear texels already times the emissive factor; bilinear, as pathwave filters them.
                tex = m["radiance_texture"]
                shape["emitter"] = {"type": "area", "radiance": {
                    "type": "bitmap", "filename": tex["exr"], "raw": True, "filter_type": "bilinear",
                    "wrap_mode": tex["wrap"]}}
            elif m.get("radiance"):
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": m["radiance"]}}
            scene[f"mesh{k}"] = shape
        # Mitsuba's default sampler, and its (0,2)-sequence one, the counterpart of pathwave's.
        start = time.perf_counter()
        self.scenes = {}
        for sampler in ("independent", "ldsampler"):
            scene["sensor"]["sampler"] = {"type": sampler}
            self.scenes[sampler] = mi.load_dict(scene)
        return {"load_s": time.perf_counter() - start, "version": mi.__version__}

    def render(self, req):
        import drjit as dr

        start = time.perf_counter()
        scene = self.scenes[req.get("sampler", "independent")]
        img = self.mi.render(scene, spp=int(req["spp"]), seed=int(req["seed"]))
        dr.eval(img)
        dr.sync_thread()
        seconds = time.perf_counter() - start
        np.asarray(img, dtype=np.float32)[..., :3].tofile(req["out"])
        return {"seconds": seconds}


def homogeneous(medium):
    """Mitsuba's homogeneous medium for pathwave's: extinction per scene unit, single-scattering albedo, HG's g."""
    sigma_t = [float(x) for x in medium["sigma_t"]]
    # RGB values given to Mitsuba must lie in [0, 1]: the extinction travels normalised, its size in `scale`.
    scale = max(sigma_t)
    return {
        "type": "homogeneous",
        "sigma_t": {"type": "rgb", "value": [x / scale for x in sigma_t]},
        "scale": scale,
        "albedo": {"type": "rgb", "value": medium["albedo"]},
        "phase": {"type": "hg", "g": medium["g"]},
        # Behind a dielectric no shadow ray reaches a light, as Mitsuba's documentation says: do not trace them.
        "sample_emitters": False,
    }


def main():
    embree, mitsuba = Embree(), Mitsuba()
    handlers = {
        "embree_load": embree.load,
        "embree_trace": embree.trace,
        "mitsuba_load": mitsuba.load,
        "mitsuba_render": mitsuba.render,
    }
    reply(ready=True)
    for line in sys.stdin:
        if not line.strip():
            continue
        req = json.loads(line)
        try:
            reply(ok=True, **handlers[req["cmd"]](req))
        except Exception as e:  # the bench prints this and stops; a traceback on stderr helps more than a crash
            import traceback

            traceback.print_exc()
            reply(ok=False, error=f"{type(e).__name__}: {e}")


if __name__ == "__main__":
    main()
