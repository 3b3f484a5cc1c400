#!/usr/bin/python3
"""The scipy peer of `specula resample`: the same reconstruction (mapping M_s, k nearest, Shepard p = 1) with
scipy's cKDTree (query with workers=-1) and a numpy weighted average, reading the same store with h5py.
Usage: peer.py STORE.h5 SAMPLES OUT.npy [-k 32] [--max-gap-deg 8.6]
Prints one JSON object: phase times, valid cells. Writes the grid (bands x 1458000 float32, -1 = no data)."""
import argparse
import json
import time

import h5py
import numpy as np
from scipy.spatial import cKDTree

ap = argparse.ArgumentParser()
ap.add_argument("store")
ap.add_argument("samples")
ap.add_argument("out")
ap.add_argument("-k", type=int, default=32)
ap.add_argument("--max-gap-deg", type=float, default=8.6)
args = ap.parse_args()
t = {}
t0 = time.perf_counter()

with h5py.File(args.store, "r") as f:
    g = f["samples"][args.samples]
    angles = g["angles"][...]
    values = g["values"][...]
t["read"] = time.perf_counter() - t0


def mapped(ti, pi_, to, po):
    d = np.abs(po - pi_) % (2 * np.pi)
    d = np.where(d > np.pi, 2 * np.pi - d, d)
    return np.stack([ti, to, d], axis=1)


t1 = time.perf_counter()
pts = mapped(angles[:, 0], angles[:, 1], angles[:, 2], angles[:, 3])
del angles
tree = cKDTree(pts)
t["tree"] = time.perf_counter() - t1

# MERL cell centres (theta_h = ((i + 1/2) / 90)^2 pi/2, theta_d and phi_d at half degrees, phi_h = 0) as standard
# angles: the difference vector turned by theta_h about the binormal.
t1 = time.perf_counter()
i, j, k = np.meshgrid(np.arange(90), np.arange(90), np.arange(180), indexing="ij")
th = ((i.ravel() + 0.5) / 90) ** 2 * np.pi / 2
td = np.radians(j.ravel() + 0.5)
pd = np.radians(k.ravel() + 0.5)
dx, dy, dz = np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)
c, s = np.cos(th), np.sin(th)
wi = np.stack([dx * c + dz * s, dy, -dx * s + dz * c], axis=1)
wo = np.stack([-dx * c + dz * s, -dy, dx * s + dz * c], axis=1)
valid = (wi[:, 2] > 0) & (wo[:, 2] > 0)
q = mapped(np.arccos(np.clip(wi[:, 2], -1, 1)), np.arctan2(wi[:, 1], wi[:, 0]),
           np.arccos(np.clip(wo[:, 2], -1, 1)), np.arctan2(wo[:, 1], wo[:, 0]))[valid]
dist, idx = tree.query(q, k=args.k, workers=-1)
t["query"] = time.perf_counter() - t1

t1 = time.perf_counter()
bands = values.shape[1]
cells = np.flatnonzero(valid)
out = np.full((bands, 90 * 90 * 180), -1.0, dtype=np.float32)
support = dist[:, 0] <= np.radians(args.max_gap_deg)
step = 1 << 15
for a in range(0, len(cells), step):
    d = dist[a:a + step]
    with np.errstate(divide="ignore"):
        w = 1.0 / d
    zero = d == 0
    w = np.where(zero.any(axis=1, keepdims=True), zero.astype(np.float64), w)
    w /= w.sum(axis=1, keepdims=True)
    est = np.einsum("ck,ckb->cb", w, values[idx[a:a + step]])
    keep = support[a:a + step]
    out[:, cells[a:a + step][keep]] = est[keep].T
t["average"] = time.perf_counter() - t1
t1 = time.perf_counter()
np.save(args.out, out)
t["write"] = time.perf_counter() - t1
t["total"] = time.perf_counter() - t0
print(json.dumps({"seconds": t, "valid_cells": int(support.sum()), "physical_cells": int(valid.sum()),
                  "samples": int(len(pts)), "bands": int(bands)}))
