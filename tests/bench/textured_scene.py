#!/usr/bin/env python3
"""A textured benchmark scene, written from nothing but numpy and PIL, so that the GPU A/B
tables have a workload where texture lookups (colour, normal map, environment map) are on
every path: gpu_ab.sh's suite scenes are untextured.

usage: python3 tests/bench/textured_scene.py OUT_DIR [QUADS_PER_SIDE]
writes OUT_DIR/terrain.obj (+ .mtl): a QUADS_PER_SIDE² grid of rolling terrain (default 600,
720k triangles) with a tiled colour map and a tangent-space normal map, a rough metal ball
made of the same grid bent into a sphere; and OUT_DIR/sky.hdr, an equirectangular sky with a
sun, for --env. Render it with, e.g.:
  runner bench --scene OUT_DIR/terrain.obj --env OUT_DIR/sky.hdr --integrator mis
"""
import os
import sys

import numpy as np
from PIL import Image

TEXTURE_SIZE = 1024  # colour and normal maps, square
TEXTURE_TILES = 8  # repeats of the maps across the terrain (UVs past 1 exercise the wrap)
SKY_WIDTH, SKY_HEIGHT = 1024, 512
SPHERE_SEGMENTS = 128


def noise(size, rng, octaves=5):
    """Smooth tileable value noise in [0, 1]: octaves of bilinearly upsampled random grids."""
    out = np.zeros((size, size))
    for o in range(octaves):
        cells = 4 << o
        grid = rng.random((cells, cells))
        x = np.arange(size) * cells / size
        i0 = np.floor(x).astype(int)
        f = x - i0
        i1 = (i0 + 1) % cells
        rows = grid[i0][:, i0] * (1 - f)[None, :] + grid[i0][:, i1] * f[None, :]
        rows1 = grid[i1][:, i0] * (1 - f)[None, :] + grid[i1][:, i1] * f[None, :]
        out += (rows * (1 - f)[:, None] + rows1 * f[:, None]) / 2 ** o
    return (out - out.min()) / (out.max() - out.min())


def write_textures(out, rng):
    h = noise(TEXTURE_SIZE, rng)
    colour = np.stack([0.35 + 0.4 * h, 0.3 + 0.45 * (1 - h), 0.15 + 0.2 * h], axis=-1)
    Image.fromarray((colour * 255).astype(np.uint8)).save(os.path.join(out, "ground.png"))
    # The normal map of the same height field (tangent space, +z out of the surface).
    dx = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) * 8
    dy = (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0)) * 8
    n = np.stack([-dx, dy, np.ones_like(h)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    Image.fromarray(((n * 0.5 + 0.5) * 255).astype(np.uint8)).save(
        os.path.join(out, "ground_normal.png"))


def write_sky(out):
    """Radiance RGBE without run-length encoding (flat scanlines), which readers accept."""
    v = (np.arange(SKY_HEIGHT) + 0.5) / SKY_HEIGHT  # 0 at the zenith
    u = (np.arange(SKY_WIDTH) + 0.5) / SKY_WIDTH
    up = np.cos(v * np.pi)[:, None] * np.ones((1, SKY_WIDTH))
    sky = np.where(up[..., None] > 0,
                   np.array([0.4, 0.6, 1.0]) * (0.3 + 0.7 * up[..., None]),
                   np.array([0.25, 0.22, 0.2]))
    # A sun 40° above the horizon, about 3° across, 2000 times the sky.
    theta, phi = np.radians(50), np.pi * 0.3
    sun = np.array([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)])
    t, p = v[:, None] * np.pi, u[None, :] * 2 * np.pi
    d = np.stack([np.sin(t) * np.cos(p), np.cos(t) * np.ones_like(p), np.sin(t) * np.sin(p)], -1)
    sky = sky + (d @ sun > np.cos(np.radians(1.5)))[..., None] * 2000.0
    m = sky.max(axis=-1)
    e = np.floor(np.log2(np.maximum(m, 1e-32))) + 1
    mant = np.clip(sky * (256.0 / 2.0 ** e)[..., None], 0, 255)
    rgbe = np.concatenate([mant, (e + 128)[..., None]], axis=-1).astype(np.uint8)
    rgbe[m < 1e-32] = 0
    with open(os.path.join(out, "sky.hdr"), "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
        f.write(f"-Y {SKY_HEIGHT} +X {SKY_WIDTH}\n".encode())
        f.write(rgbe.tobytes())


def grid(n):
    """Vertex (i, j) of an (n + 1)² grid in [0, 1]², and the two triangles of each quad."""
    s = np.linspace(0, 1, n + 1)
    u, v = np.meshgrid(s, s)
    i = np.arange(n)
    a = (i[:, None] * (n + 1) + i[None, :]).ravel()
    quads = np.stack([a, a + 1, a + n + 2, a + n + 1], -1)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return u.ravel(), v.ravel(), tris


def write_obj(out, n):
    lines = ["mtllib terrain.mtl"]
    vertex_base = 1

    def mesh(positions, normals, uvs, tris, material):
        nonlocal vertex_base
        lines.append(f"usemtl {material}")
        lines.extend(f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in positions)
        lines.extend(f"vn {x:.4f} {y:.4f} {z:.4f}" for x, y, z in normals)
        lines.extend(f"vt {s:.5f} {t:.5f}" for s, t in uvs)
        b = vertex_base
        lines.extend(f"f {a + b}/{a + b}/{a + b} {c + b}/{c + b}/{c + b} {d + b}/{d + b}/{d + b}"
                     for a, c, d in tris)
        vertex_base += len(positions)

    u, v, tris = grid(n)
    x, z = (u - 0.5) * 20, (v - 0.5) * 20
    y = 0.6 * np.sin(x * 0.7) * np.cos(z * 0.5) + 0.25 * np.sin(x * 2.3 + z * 1.7)
    dydx = 0.42 * np.cos(x * 0.7) * np.cos(z * 0.5) + 0.575 * np.cos(x * 2.3 + z * 1.7)
    dydz = -0.3 * np.sin(x * 0.7) * np.sin(z * 0.5) + 0.425 * np.cos(x * 2.3 + z * 1.7)
    normals = np.stack([-dydx, np.ones_like(x), -dydz], -1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    # Counter-clockwise seen from above (+y).
    mesh(np.stack([x, y, z], -1), normals, np.stack([u, v], -1) * TEXTURE_TILES,
         tris[:, [0, 2, 1]], "ground")

    su, sv, stris = grid(SPHERE_SEGMENTS)
    t, p = sv * np.pi, su * 2 * np.pi
    d = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1)
    mesh(d * 2 + np.array([0, 3, 0]), d, np.stack([su, sv], -1), stris, "metal")
    with open(os.path.join(out, "terrain.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(out, "terrain.mtl"), "w") as f:
        f.write("newmtl ground\nKd 1 1 1\nmap_Kd ground.png\nnorm ground_normal.png\n\n"
                "newmtl metal\nKd 0.9 0.8 0.6\nPm 1\nPr 0.3\n")


def main():
    out = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 600
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(7)
    write_textures(out, rng)
    write_sky(out)
    write_obj(out, n)


if __name__ == "__main__":
    main()
