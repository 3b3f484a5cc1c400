#!/usr/bin/python3
"""Figures 7.2 and 7.3 of the reference (Braley 2012, §7.3) from a PCA of a specula store, without a notebook:
  components.png   the first 8 principal components against wavelength (figure 7.2)
  eigenvalues.png  every eigenvalue on a log scale, where the plateau after the 6th shows (figure 7.3)
The PCA streams every valid spectrum of the selected images (or one collection) through specula.pca; with --basis
a basis already in the store is plotted instead.

Usage: examples/python/pca_figures.py STORE.h5 -o DIR [--images GLOB ...] [--collection NAME] [--basis NAME]
Needs the specula module on PYTHONPATH (build/python in a build tree, docs/python.md) and python3-matplotlib."""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import specula  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("-o", "--output", required=True, help="directory for the two PNGs")
    ap.add_argument("--images", nargs="*", help="image name globs (default: every image)")
    ap.add_argument("--collection", default="", help="use this collection instead of images")
    ap.add_argument("--basis", help="plot this PCA basis of the store instead of computing one")
    ap.add_argument("--components", type=int, default=8, help="components in figure 7.2")
    args = ap.parse_args()

    try:
        if args.basis:
            basis = specula.Store(args.store).basis(args.basis)
        else:
            basis = specula.pca(args.store, images=args.images, collection=args.collection)
    except specula.Error as e:
        sys.exit(f"pca_figures: {e}")
    if basis.method != "pca":
        sys.exit(f"pca_figures: basis {args.basis} is {basis.method}, not pca")
    os.makedirs(args.output, exist_ok=True)
    nm = basis.wavelengths
    k = min(args.components, basis.k)

    fig, ax = plt.subplots(figsize=(9, 5.5))
    for i in range(k):
        ax.plot(nm, basis.components[i], label=f"PC {i + 1}", linewidth=1.6 if i < 3 else 1.0)
    ax.axhline(0, color="0.6", linewidth=0.6)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("component value")
    ax.set_title(f"First {k} principal components of {basis.n:,} spectra (figure 7.2)")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(args.output, "components.png"), dpi=110)
    plt.close(fig)

    ev = basis.eigenvalues
    fig, ax = plt.subplots(figsize=(8, 5.5))
    index = np.arange(1, ev.size + 1)
    positive = ev > 0
    ax.semilogy(index[positive], ev[positive], "o-", markersize=4)
    ax.set_xlabel("principal component")
    ax.set_ylabel("eigenvalue")
    ax.set_title(f"Eigenvalues of the covariance of {basis.n:,} spectra (figure 7.3)")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(os.path.join(args.output, "eigenvalues.png"), dpi=110)
    plt.close(fig)

    cumulative = np.cumsum(basis.explained_variance_ratio)
    print(f"PCA of {basis.n} spectra ({nm.size} bands): first 6 components explain {100 * cumulative[5]:.4f} % of "
          f"the variance; wrote components.png and eigenvalues.png in {args.output}")


if __name__ == "__main__":
    main()
