"""numpy peer for the block reader benchmark: streams the same valid spectra from raw float32 BIP files
(one per image, exported by `specula export --format envi --interleave bip`) with np.memmap, applies the
mask, converts each block to float64 as the covariance pass needs, and sums it.
Usage: numpy_peer.py RAW_DIR [repeats]  -> one JSON line."""
import glob
import json
import os
import resource
import sys
import time

import numpy as np

raw_dir = sys.argv[1]
repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
images = []
for hdr in sorted(glob.glob(os.path.join(raw_dir, "*.hdr"))):
    fields = {}
    for line in open(hdr):
        if "=" in line:
            k, v = line.split("=", 1)
            fields[k.strip().lower()] = v.strip()
    h, w, b = int(fields["lines"]), int(fields["samples"]), int(fields["bands"])
    images.append((hdr[:-4] + ".raw", hdr[:-4] + ".mask", h, w, b))

block_rows = 65536
best = float("inf")
for _ in range(repeats):
    t0 = time.perf_counter()
    total, n = 0.0, 0
    for raw, mask_path, h, w, b in images:
        cube = np.memmap(raw, dtype="<f4", mode="r", shape=(h * w, b))
        mask = np.fromfile(mask_path, dtype=np.uint8).astype(bool) if os.path.exists(mask_path) else None
        for r0 in range(0, h * w, block_rows):
            blk = cube[r0:r0 + block_rows]
            if mask is not None:
                blk = blk[mask[r0:r0 + block_rows]]
            blk = blk.astype(np.float64)
            total += blk.sum()
            n += blk.shape[0]
    best = min(best, time.perf_counter() - t0)
bands = images[0][4]
print(json.dumps({"spectra": n, "seconds": best, "spectra_per_s": n / best, "gb_per_s": n * bands * 4 / best / 1e9,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "checksum": total}))
