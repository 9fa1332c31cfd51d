"""Mitsuba 3 references for tests/surfaces.rs: the Cornell walls and light with two smooth
(vertex-normal) spheres, in two material sets, rendered from the very OBJ files the test
writes (`cargo test --release --test surfaces` leaves them in
$CARGO_TARGET_TMPDIR/surfaces_mitsuba, e.g. target/tmp/surfaces_mitsuba).

    pip install mitsuba            # 3.x, scalar_rgb on the CPU
    python3 tests/references/mitsuba_surfaces.py DIR

Each OBJ group (one per `usemtl`) becomes a Mitsuba shape with the BSDF the runner maps its
MTL material to (README, "Materials"): Lambertian -> two-sided diffuse (our surfaces are
two-sided), illum 3 with black Kd -> conductor of specular_reflectance Ks and no Fresnel
falloff (Schlick with F0 = 1 is 1), illum 7 -> dielectric of index Ni, Ks/Ns glossy with
black Kd -> roughconductor (GGX, alpha = sqrt(2 / (Ns + 2))) with Ks = 1 (Schlick's F is 1),
illum 7 with Pr -> roughdielectric (GGX, alpha = Pr^2). Only the materials the test uses are
mapped here.
"""
import math
import os
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")

WIDTH = HEIGHT = 96
SPP = 4096


def split_obj(path, out_dir):
    """One OBJ per `usemtl` group, with the vertices (and normals) it uses."""
    v, vn, groups, current = [], [], {}, None
    for line in open(path):
        w = line.split()
        if not w:
            continue
        if w[0] == "v":
            v.append(w[1:4])
        elif w[0] == "vn":
            vn.append(w[1:4])
        elif w[0] == "usemtl":
            current = w[1]
            groups.setdefault(current, [])
        elif w[0] == "f":
            groups[current].append(w[1:])
    files = {}
    for name, faces in groups.items():
        lines, vmap, nmap = [], {}, {}
        for face in faces:
            out = []
            for corner in face:
                parts = corner.split("/")
                vi = int(parts[0])
                if vi not in vmap:
                    vmap[vi] = len(vmap) + 1
                    lines.append("v " + " ".join(v[vi - 1]))
                ni = int(parts[2]) if len(parts) > 2 and parts[2] else None
                if ni is not None and ni not in nmap:
                    nmap[ni] = len(nmap) + 1
                    lines.append("vn " + " ".join(vn[ni - 1]))
                out.append(f"{vmap[vi]}//{nmap[ni]}" if ni is not None else f"{vmap[vi]}")
            lines.append("f " + " ".join(out))
        file = os.path.join(out_dir, f"{os.path.basename(path)}.{name}.obj")
        open(file, "w").write("\n".join(lines) + "\n")
        files[name] = file
    return files


def diffuse(rgb):
    return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}}}


BSDFS = {
    "white": diffuse([0.725, 0.71, 0.68]),
    "red": diffuse([0.63, 0.065, 0.05]),
    "green": diffuse([0.14, 0.45, 0.091]),
    "light": diffuse([0.78, 0.78, 0.78]),
    "mirror": {"type": "conductor", "material": "none", "specular_reflectance": {"type": "rgb", "value": [1, 1, 1]}},
    "glass": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0},
    "metal": {
        "type": "roughconductor",
        "material": "none",
        "distribution": "ggx",
        "alpha": math.sqrt(2 / (30 + 2)),
        "specular_reflectance": {"type": "rgb", "value": [1, 1, 1]},
    },
    "frosted": {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.5 * 0.5, "int_ior": 1.5, "ext_ior": 1.0},
}


def render(scene_obj, out_exr):
    tmp = os.path.join(os.path.dirname(scene_obj), "mitsuba_parts")
    os.makedirs(tmp, exist_ok=True)
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 8},
        "sensor": {
            "type": "perspective",
            "fov": 39.3,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=[278, 273, -800], target=[278, 273, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": WIDTH, "height": HEIGHT, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": SPP},
        },
    }
    for name, file in split_obj(scene_obj, tmp).items():
        shape = {"type": "obj", "filename": file, "bsdf": BSDFS[name]}
        if name == "light":
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": [17, 12, 4]}}
        scene[name] = shape
    image = mi.render(mi.load_dict(scene))
    mi.util.write_bitmap(out_exr, image)


if __name__ == "__main__":
    d = sys.argv[1]
    here = os.path.dirname(os.path.abspath(__file__))
    for name in ["mirror_glass", "rough"]:
        render(os.path.join(d, f"{name}.obj"), os.path.join(here, f"surfaces_{name}_96.exr"))
        print("wrote", name)
