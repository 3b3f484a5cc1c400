"""Independent NBRDF evaluation for tests/codec/nbrdf_test.cpp: h5py reads the Keras weights, numpy runs the
6 -> 21 -> 21 -> 3 network (ReLU, ReLU, exp(x) - 1) at MERL cell centres computed here from the indices
(docs/store-format.md), and prints one line "i j k r g b" per cell (r g b = -1 for a cell below the horizon).

usage: nbrdf_reference.py WEIGHTS.h5 i,j,k [i,j,k ...]
"""
import sys

import h5py
import numpy as np


def main():
    with h5py.File(sys.argv[1], "r") as f:
        layers = [(f[f"dense_{n}/dense_{n}/kernel:0"][...].astype(np.float64),
                   f[f"dense_{n}/dense_{n}/bias:0"][...].astype(np.float64)) for n in (1, 2, 3)]
    for arg in sys.argv[2:]:
        i, j, k = (int(v) for v in arg.split(","))
        th = ((i + 0.5) / 90.0) ** 2 * np.pi / 2
        td = (j + 0.5) * np.pi / 180
        pd = (k + 0.5) * np.pi / 180
        h = np.array([np.sin(th), 0.0, np.cos(th)])
        d = np.array([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)])
        # The incident and outgoing directions: d rotated by theta_h about y (phi_h = 0), and its mirror about h.
        ry = np.array([[np.cos(th), 0, np.sin(th)], [0, 1, 0], [-np.sin(th), 0, np.cos(th)]])
        wi = ry @ d
        wo = 2 * np.dot(wi, h) * h - wi
        if wi[2] <= 0 or wo[2] <= 0:
            print(i, j, k, -1, -1, -1)
            continue
        x = np.concatenate([h, d])
        for n, (kern, bias) in enumerate(layers):
            x = x @ kern + bias
            x = np.maximum(x, 0) if n < 2 else np.expm1(x)
        x = np.maximum(x, 0)
        print(i, j, k, *(f"{v:.17g}" for v in x))


if __name__ == "__main__":
    main()
