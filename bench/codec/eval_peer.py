"""numpy peer for the .spc evaluation benchmark: the decoded float32 grid (bands x 90 x 90 x 180, band planes)
looked up by nearest cell exactly as MERL's BRDFRead.cpp (half/difference angles in float64, theta_h index
floor(90 sqrt(theta_h / (pi/2))), theta_d floor(90 theta_d / (pi/2)), phi_d shifted by pi when negative and
floor(180 phi_d / pi), each clamped), vectorised over every direction pair, n x bands float32 out.
Usage: eval_peer.py DIR [repeats]  (DIR from spc_eval_bench: wi.f32, wo.f32, grid.f32, grid.json) -> one JSON line."""
import json
import os
import sys
import time

import numpy as np

d = sys.argv[1]
repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
meta = json.load(open(os.path.join(d, "grid.json")))
bands, scale = meta["bands"], meta["scale"]
wi = np.fromfile(os.path.join(d, "wi.f32"), dtype="<f4").reshape(-1, 3)
wo = np.fromfile(os.path.join(d, "wo.f32"), dtype="<f4").reshape(-1, 3)
grid = np.fromfile(os.path.join(d, "grid.f32"), dtype="<f4").reshape(bands, -1)


def lookup(wi, wo):
    i = wi.astype(np.float64)
    o = wo.astype(np.float64)
    i /= np.linalg.norm(i, axis=1)[:, None]
    o /= np.linalg.norm(o, axis=1)[:, None]
    h = i + o
    h /= np.linalg.norm(h, axis=1)[:, None]
    theta_h = np.arccos(np.clip(h[:, 2], -1, 1))
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    # wi turned by -phi_h about the normal, then by -theta_h about the binormal (BRDFRead.cpp's rotate_vector)
    c, s = np.cos(phi_h), np.sin(phi_h)
    ux, uy, uz = c * i[:, 0] + s * i[:, 1], c * i[:, 1] - s * i[:, 0], i[:, 2]
    ct, st = np.cos(theta_h), np.sin(theta_h)
    dx, dy, dz = ct * ux - st * uz, uy, st * ux + ct * uz
    theta_d = np.arccos(np.clip(dz / np.sqrt(dx * dx + dy * dy + dz * dz), -1, 1))
    phi_d = np.arctan2(dy, dx)
    phi_d = np.where(phi_d < 0, phi_d + np.pi, phi_d)
    th = np.clip(np.floor(np.sqrt(np.maximum(theta_h, 0) / (np.pi / 2) * 90 * 90)), 0, 89).astype(np.int64)
    td = np.clip(np.floor(theta_d / (np.pi / 2) * 90), 0, 89).astype(np.int64)
    pd = np.clip(np.floor(phi_d / np.pi * 180), 0, 179).astype(np.int64)
    cell = pd + 180 * (td + 90 * th)
    return np.maximum(grid[:, cell].T, 0) * np.float32(scale)


best = float("inf")
for _ in range(repeats):
    t0 = time.perf_counter()
    out = lookup(wi, wo)
    best = min(best, time.perf_counter() - t0)
print(json.dumps({"pairs": len(wi), "numpy_lookup_per_s": len(wi) / best, "numpy": np.__version__}))
