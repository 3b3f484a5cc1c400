"""scikit-learn peers for the NMF benchmark: the valid spectra of a specula store (read with h5py, mask
applied, negatives clipped to zero exactly as `specula nmf` does) factored in memory at rank k.
Usage: peers.py METHOD STORE -k K  -> one JSON line with seconds (fit only), rel_error ||X - WH||_F / ||X||_F,
iterations, and for "bound" the rank-k truncated-SVD error from the eigenvalues of X^T X.
Methods: bound | minibatch (MiniBatchNMF defaults) | minibatch20 (tol=0, max_iter=20, max_no_improvement=None) | cd (NMF(solver="cd"))."""
import argparse
import json
import resource
import time

import h5py
import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("method", choices=["bound", "minibatch", "minibatch20", "cd"])
ap.add_argument("store")
ap.add_argument("-k", type=int, default=6)
args = ap.parse_args()


def load(path):
    parts = []
    with h5py.File(path, "r") as f:
        for name in f["images"]:
            img = f["images"][name]
            cube, mask = img["cube"][...], img["mask"][...].view(bool)
            parts.append(cube[mask].astype(np.float64))
    x = np.concatenate(parts)
    return np.maximum(x, 0.0)


x = load(args.store)
xx = float(np.sum(x * x))
out = {"method": args.method, "n": int(x.shape[0]), "bands": int(x.shape[1]), "k": args.k}
if args.method == "bound":
    ev = np.clip(np.linalg.eigvalsh(x.T @ x), 0, None)  # ascending
    out["svd_bound"] = float(np.sqrt(ev[: x.shape[1] - args.k].sum() / ev.sum()))
else:
    from sklearn.decomposition import NMF, MiniBatchNMF
    if args.method == "minibatch":
        est = MiniBatchNMF(n_components=args.k, random_state=0)
    elif args.method == "minibatch20":
        est = MiniBatchNMF(n_components=args.k, random_state=0, tol=0, max_iter=20, max_no_improvement=None)
    else:
        est = NMF(n_components=args.k, solver="cd", random_state=0)
    t0 = time.perf_counter()
    w = est.fit_transform(x)
    out["seconds"] = time.perf_counter() - t0
    h = est.components_
    out["rel_error"] = float(np.linalg.norm(x - w @ h) / np.sqrt(xx))
    out["iterations"] = int(est.n_iter_)
out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
