"""The peer's time for our AO workload: Mitsuba 3's `ray_test` (OptiX; the H100 has no RT
cores, so OptiX traverses its BVH in software as we do) on the triangles and AO points that
`runner/examples/dump_ao.rs` writes for a frame (1 spp, each pixel's visible point, its
origin already off the surface, its normal as a 16-bit octahedral word). Each point gets the
frame's AO rays: `rays` cosine-weighted directions about its normal of length `distance`,
drawn here with numpy (not our keyed strata: the same distribution, not the same rays).
Prints the OptiX time of one wavefront of all of them (median of `--runs`, after warm-up),
rays per second and the share that escaped; the AO kernel's own time is `runner bench` on
the same scene (tests/bench/peer_optix.sh runs both).

usage: python3 tests/bench/peer_optix.py DUMP_DIR [--variant cuda_ad_rgb] [--runs 5]
"""
import argparse
import statistics
import sys
import time

import numpy as np

INVALID = 0xFFFFFFFF


def decode_unit(words):
    """`types::decode_unit`: two 16-bit octahedral coordinates to unit vectors."""
    u = (words & 0xFFFF).astype(np.float32) / np.float32(65535.0) * 2 - 1
    v = (words >> 16).astype(np.float32) / np.float32(65535.0) * 2 - 1
    z = 1 - np.abs(u) - np.abs(v)
    t = np.maximum(-z, 0)
    x = np.where(u >= 0, u - t, u + t)
    y = np.where(v >= 0, v - t, v + t)
    n = np.stack([x, y, z], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def orthonormal_basis(n):
    """`sampling::orthonormal_basis` (Duff et al. 2017), row-wise."""
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0).astype(np.float32)
    a = -1 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    bt = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, bt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dump")
    ap.add_argument("--variant", default="cuda_ad_rgb")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--chunk", type=int, default=1 << 26, help="rays per ray_test call")
    a = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(a.variant)
    w, h, rays, distance, _order, _nodes, _tris = open(f"{a.dump}/params.txt").read().split()
    w, h, rays, distance = int(w), int(h), int(rays), float(distance)

    # The GPU's triangle buffer holds a spatially split triangle once per part: once here.
    tris = np.fromfile(f"{a.dump}/tris.bin", dtype=np.uint32).reshape(-1, 12)
    tris = np.unique(tris, axis=0)
    corners = tris[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]].view(np.float32).reshape(-1, 3)
    count = len(tris)
    mesh = mi.Mesh("suite", vertex_count=3 * count, face_count=count, has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(corners.ravel())
    params["faces"] = mi.UInt32(np.arange(3 * count, dtype=np.uint32))
    params.update()
    t0 = time.perf_counter()
    scene = mi.load_dict({"type": "scene", "mesh": mesh})
    build = time.perf_counter() - t0

    points = np.fromfile(f"{a.dump}/points.bin", dtype=np.uint32).reshape(-1, 6)
    points = points[points[:, 5] != INVALID]
    origin = points[:, :3].copy().view(np.float32)
    n = decode_unit(points[:, 3])
    t, b = orthonormal_basis(n)
    rng = np.random.default_rng(1)
    total = len(points) * rays

    # The wavefront in chunks of whole points, made once and kept on the GPU.
    per_chunk = max(1, a.chunk // rays)
    chunks = []
    for s in range(0, len(points), per_chunk):
        e = min(s + per_chunk, len(points))
        m = (e - s) * rays
        u1 = rng.random(m, dtype=np.float32)
        u2 = rng.random(m, dtype=np.float32)
        r = np.sqrt(u1)
        phi = np.float32(2 * np.pi) * u2
        local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1 - u1, 0))], 1)
        idx = np.repeat(np.arange(s, e), rays)
        d = t[idx] * local[:, :1] + b[idx] * local[:, 1:2] + n[idx] * local[:, 2:3]
        o = origin[idx]
        ray = mi.Ray3f(
            mi.Point3f(*(mi.Float(np.ascontiguousarray(o[:, k])) for k in range(3))),
            mi.Vector3f(*(mi.Float(np.ascontiguousarray(d[:, k].astype(np.float32))) for k in range(3))),
        )
        ray.maxt = mi.Float(distance)
        dr.eval(ray)
        chunks.append(ray)
    dr.sync_thread()

    def frame():
        hits = [scene.ray_test(ray) for ray in chunks]
        dr.eval(hits)
        dr.sync_thread()
        return hits

    for _ in range(a.warmup):
        frame()
    times = []
    for _ in range(a.runs):
        t0 = time.perf_counter()
        hits = frame()
        times.append(time.perf_counter() - t0)
    blocked = sum(int(np.count_nonzero(hit.numpy())) for hit in hits)
    ms = 1e3 * statistics.median(times)
    print(
        f"{a.dump}: {count} triangles, OptiX build {build:.2f} s; {total} AO rays of {len(points)} points, "
        f"{100 * (1 - blocked / total):.1f}% escape; ray_test {ms:.2f} ms "
        f"({total / ms / 1e6:.2f} G rays/s; runs {' '.join(f'{1e3 * x:.2f}' for x in times)})"
    )
    sys.stdout.flush()


if __name__ == "__main__":
    main()
