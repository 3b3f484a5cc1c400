"""numpy / scikit-learn peers for the PCA benchmark. Each reads every valid spectrum of a specula store with
h5py, one chunk of rows at a time (row slabs matching the cube's chunk rows, so every chunk is read once),
applies the mask and works in float64.
Usage: peers.py METHOD STORE [--repeats N] [--budget SECONDS] [--limit SECONDS]  -> one JSON line.
Methods:
  twopass  the float64 reference: pass 1 the mean, pass 2 the Gram of the centred spectra, np.linalg.eigh.
  gram     the careful one-pass answer: per chunk its mean and centred Gram (float64 BLAS), Chan merges.
  ipca     sklearn.decomposition.IncrementalPCA.partial_fit, one batch per chunk. If after --budget seconds
           (default 30) the projected total exceeds --limit seconds (default 600), it stops and extrapolates
           the time linearly from the spectra it processed ("extrapolated": true in the JSON).
Eigenvalues are those of the sample covariance (divisor n - 1), descending, as `specula pca` reports them."""
import argparse
import json
import resource
import time

import h5py
import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("method", choices=["twopass", "gram", "ipca"])
ap.add_argument("store")
ap.add_argument("--repeats", type=int, default=1)
ap.add_argument("--budget", type=float, default=30.0)
ap.add_argument("--limit", type=float, default=600.0)
args = ap.parse_args()


def chunks(f):
    """Yields the valid spectra of every image, one chunk row slab at a time, as float64 (n, bands)."""
    for name in f["images"]:
        img = f["images"][name]
        cube, mask = img["cube"], img["mask"]
        h, w, b = cube.shape
        rows = cube.chunks[0] if cube.chunks else max(1, (1 << 20) // (w * b * 4))
        buf = np.empty((rows, w, b), dtype=np.float32)
        mbuf = np.empty((rows, w), dtype=np.uint8)
        for r0 in range(0, h, rows):
            r1 = min(h, r0 + rows)
            c, m = buf[:r1 - r0], mbuf[:r1 - r0]
            cube.read_direct(c, np.s_[r0:r1])
            mask.read_direct(m, np.s_[r0:r1])
            x = c[m.view(bool)]
            if x.shape[0]:
                yield x.astype(np.float64)


def total_valid(f):
    return int(sum(int(f["images"][n].attrs["valid_pixels"]) for n in f["images"]))


def eigenvalues(scatter, n):
    return np.linalg.eigh(scatter / (n - 1))[0][::-1]


def twopass(f):
    n, s = 0, None
    for x in chunks(f):
        n += x.shape[0]
        s = x.sum(axis=0) if s is None else s + x.sum(axis=0)
    mean = s / n
    scatter = None
    for x in chunks(f):
        x -= mean
        g = x.T @ x
        scatter = g if scatter is None else scatter + g
    return n, eigenvalues(scatter, n), {}


def gram(f):
    n, mean, scatter = 0, None, None
    for x in chunks(f):
        nb = x.shape[0]
        mb = x.mean(axis=0)
        x -= mb
        sb = x.T @ x
        if n == 0:
            n, mean, scatter = nb, mb, sb
            continue
        delta = mb - mean
        nt = n + nb
        mean = mean + delta * (nb / nt)
        scatter = scatter + sb + np.outer(delta, delta) * (n * nb / nt)
        n = nt
    return n, eigenvalues(scatter, n), {}


if args.method == "ipca":  # imported here so that its import time stays out of the measurement
    import sklearn
    from sklearn.decomposition import IncrementalPCA


def ipca(f):
    total = total_valid(f)
    est = IncrementalPCA()  # n_components=None: all of them (min of first batch size and bands)
    n, t0, carry = 0, time.perf_counter(), None
    extrapolated = False
    for x in chunks(f):
        if carry is not None:  # the first batch must hold at least `bands` spectra to fix n_components_ = bands
            x, carry = np.vstack([carry, x]), None
        if n == 0 and x.shape[0] < x.shape[1]:
            carry = x
            continue
        est.partial_fit(x)
        n += x.shape[0]
        elapsed = time.perf_counter() - t0
        if elapsed > args.budget and elapsed * total / n > args.limit and n < total:
            extrapolated = True
            break
    return n, np.asarray(est.explained_variance_), {"extrapolated": extrapolated, "total_spectra": total,
                                                     "sklearn": sklearn.__version__}


with h5py.File(args.store, "r") as f:
    best, result = float("inf"), None
    for _ in range(args.repeats):
        t0, ru0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF)
        n, ev, extra = {"twopass": twopass, "gram": gram, "ipca": ipca}[args.method](f)
        dt, ru1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_SELF)
        if dt < best:
            cpu = ru1.ru_utime - ru0.ru_utime + ru1.ru_stime - ru0.ru_stime
            best, result = dt, (n, ev, extra)
n, ev, extra = result
out = {"method": args.method, "spectra": n, "seconds": best, "cpu_seconds": cpu, "spectra_per_s": n / best,
       "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "eigenvalues": ev.tolist(),
       "numpy": np.__version__, "h5py": h5py.__version__}
out.update(extra)
if extra.get("extrapolated"):
    out["measured_seconds"] = best
    out["cpu_seconds"] = cpu * extra["total_spectra"] / n
    out["measured_spectra"] = n
    out["seconds"] = best * extra["total_spectra"] / n
    out["spectra"] = extra["total_spectra"]
print(json.dumps(out))
